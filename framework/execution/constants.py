"""Time limits of an evaluation (crashlab.execution)."""
# s per evaluation: the slowest built-in model (exudyn, 1 ms implicit steps) takes about 1 s for a
# two-car crash to rest and 0.1-0.3 s is typical (README, "Speed"); 60 s is 60 x that, so only a hung
# or runaway simulation reaches it, and it bounds what one hang costs a run
DEFAULT_TIMEOUT_S = 60.0
# s, the shortest limit (0 aside: no limit): a worker's round trip (pickling, the pipe) takes milliseconds, a
# batch of n scenes gets n x the limit and each worker's first call FIRST_CALL_GRACE_S more, so below this a
# limit is not what it says (1 ns failed 2 of 12 evaluations and let 10 through, a probe of 2026-11-28)
TIMEOUT_MIN_S = 0.1
FIRST_CALL_GRACE_S = 600.0  # s on top of the first call in each worker: numba compiles on first use
