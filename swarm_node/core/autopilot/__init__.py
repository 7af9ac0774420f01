"""Autopilot (ArduPilot over MAVLink) as seen by the pure cores: the state the link's
tracker maintains (`state`), the requests cores make of it (`requests`) and the
autopilot-neutral mission steps planners produce (`items`). The MAVLink I/O lives in
swarm_node.runtime."""
