"""Forces in real time (METHOD.md section 3, step 7): the recursive least-squares kernel
(:mod:`.rls`), the streaming estimator built on it (:mod:`.estimator`), and the replay of a
recorded run through it with its table writer (:mod:`.replay`); under any drive, the batch
estimate over a window that slides with the stream (:mod:`.any_drive`)."""

from .estimator import StreamEstimator
from .replay import replay, write_stream_csv
from .rls import harmonic_start, harmonic_update, rls_start, rls_update, steady_count

__all__ = [
    "StreamEstimator",
    "harmonic_start",
    "harmonic_update",
    "replay",
    "rls_start",
    "rls_update",
    "steady_count",
    "write_stream_csv",
]
