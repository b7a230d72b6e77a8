"""Running installations: the config schema, the shared world of a colony, the offline runner
(simulated clock, as fast as possible) and the live runner (wall clock, devices)."""
