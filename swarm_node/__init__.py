"""swarm_node: the peer on each vehicle's companion computer.

`core/` holds the pure, sans-I/O logic (autopilot state tracking, monitoring, swarm
membership, state machine, mission management, planning, avoidance); `runtime/` holds
the I/O shell (Zenoh, MAVLink, SQLite) that feeds the cores and executes their actions.
"""
