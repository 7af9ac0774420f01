"""Builds a NodeRuntime from a NodeConfig: identity and parameters, the autopilot link,
the Zenoh session."""

from __future__ import annotations

import logging
from collections.abc import Callable

from swarm_proto import Clock

from ..core.profile import VehicleProfile
from .config import NodeConfig, profile_from_config
from .node import AutopilotPort, NodeRuntime

log = logging.getLogger("swarm_node")


def resolve_profile(cfg: NodeConfig) -> VehicleProfile:
    """The node's identity and parameters: the config's [profile] table (the swarm
    database takes over when it is configured)."""
    return profile_from_config(cfg)


#: Silence that counts as a lost autopilot link. Telemetry is requested at 10 Hz, so this
#: is six missed position messages; with the 5 Hz state machine it keeps link loss ->
#: STATE_EMERGENCY under 1 s.
LINK_TIMEOUT_S = 0.6


def open_autopilot(
    cfg: NodeConfig,
    profile: VehicleProfile,
    clock: Clock,
    on_event: Callable[[object], None] | None = None,
) -> AutopilotPort | None:
    """The MAVLink link to the autopilot (None: a node without one). The vehicle type
    comes from the profile: a QuadPlane reports FIXED_WING in its HEARTBEAT."""
    if not cfg.autopilot:
        return None
    from swarm_proto import VehicleType

    from ..core.autopilot.link import LinkSettings
    from .autopilot_link import AutopilotLink

    vt = profile.vehicle_type if profile.vehicle_type != VehicleType.OTHER else None
    link = AutopilotLink(
        cfg.autopilot,
        clock,
        vehicle_type=vt,
        on_event=on_event,
        settings=LinkSettings(link_timeout_s=LINK_TIMEOUT_S),
        name=f"autopilot-{profile.vehicle_id}",
    )
    link.start()
    return link


def build_node(cfg: NodeConfig, clock: Clock) -> NodeRuntime:
    profile = resolve_profile(cfg)
    autopilot = open_autopilot(cfg, profile, clock)
    log.info(
        "node %d (%s, %s) starting", profile.vehicle_id, profile.model, profile.vehicle_type.name
    )
    return NodeRuntime(cfg, profile, clock, autopilot)
