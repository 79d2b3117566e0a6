"""Time limits of an evaluation (crashlab.execution)."""
# s per evaluation: the slowest built-in model (exudyn, 1 ms implicit steps) takes about 1 s for a
# two-car crash to rest and 0.1-0.3 s is typical (README, "Speed"); 60 s is 60 x that, so only a hung
# or runaway simulation reaches it, and it bounds what one hang costs a run
DEFAULT_TIMEOUT_S = 60.0
FIRST_CALL_GRACE_S = 600.0  # s on top of the first call in each worker: numba compiles on first use
