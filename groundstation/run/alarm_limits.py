"""The alarms' default limits, apart so that `dive --help` shows them without loading the protocol."""

DEPTH_LIMIT_M = 2.5  # the deepest target or hover depth (SPEC.md)
LINK_LOST_S = 5.0  # the agent silent, or the link lost, this long
