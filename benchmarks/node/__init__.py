"""Benchmarks of the running node over DDS: real time steered by a player (realtime, player), a
SIGKILL's loss (sigkill), a flood of commands (flood, flooder)."""
