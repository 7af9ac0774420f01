"""Autopilot (ArduPilot over MAVLink) as seen by the pure cores.

Types every core uses: the state the link's tracker maintains (`state`), the requests
cores make of it and their results (`requests`), the events it reports (`events`) and
the autopilot-neutral mission steps planners produce (`items`).

The link itself, sans I/O: `link.LinkCore` composes `framing` (bytes <-> messages),
`tracker` (messages -> AutopilotState), `streams` (telemetry requests), `plans` and
`runner` (requests -> MAVLink with COMMAND_ACK handling), `mission_protocol` and
`conversion` (mission, fence, rally), `status` (-> VehicleStatus). The thread and the
sockets are in swarm_node.runtime.autopilot_link; see docs/autopilot-link.md.
"""
