"""Forces in real time (METHOD.md section 3, step 7): the recursive least-squares kernel
(:mod:`.rls`), the streaming estimator built on it (:mod:`.estimator`), and the replay of a
recorded run through it with its table writer (:mod:`.replay`); under any drive, the batch
estimate over a window that slides with the stream (:mod:`.any_drive`)."""

from .estimator import DEFAULT_MEMORY_PERIODS, StreamEstimator
from .replay import replay, write_stream_csv
from .rls import (
    PRIOR,
    HarmonicState,
    RlsState,
    chunk_limit,
    harmonic_information,
    harmonic_start,
    harmonic_update,
    rls_start,
    rls_update,
    steady_count,
)

__all__ = [
    "DEFAULT_MEMORY_PERIODS",
    "PRIOR",
    "HarmonicState",
    "RlsState",
    "StreamEstimator",
    "chunk_limit",
    "harmonic_information",
    "harmonic_start",
    "harmonic_update",
    "replay",
    "rls_start",
    "rls_update",
    "steady_count",
    "write_stream_csv",
]
