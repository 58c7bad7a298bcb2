"""Many jobs at once (INTERFACES.md section 5: ``--workers``, ``--scheduler``): a process pool
on this machine, or a Dask cluster (:mod:`.pool`), and the jobs the commands spread over them
(:mod:`.jobs`), and the threads every command and API call runs on (:mod:`.threads`)."""


from .pool import run_jobs

__all__ = ["run_jobs"]
