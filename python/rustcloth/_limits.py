"""Limits on what one request may ask for, shared by the command line and the sweeps."""

#: The most steps one run may take (2.8 hours of a scene at dt = 1 ms): more is a typo or an
#: attack, not a run anyone waits for, and would overflow the core's step counter long before
#: it finished.
MAX_STEPS = 10_000_000
