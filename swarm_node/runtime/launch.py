"""Builds a NodeRuntime from a NodeConfig: identity and parameters, the autopilot link,
the Zenoh session."""

from __future__ import annotations

import logging

from swarm_proto import Clock

from ..core.profile import VehicleProfile
from .config import NodeConfig, profile_from_config
from .node import AutopilotPort, NodeRuntime

log = logging.getLogger("swarm_node")


def resolve_profile(cfg: NodeConfig) -> VehicleProfile:
    """The node's identity and parameters: the config's [profile] table (the swarm
    database takes over when it is configured)."""
    return profile_from_config(cfg)


def open_autopilot(cfg: NodeConfig, profile: VehicleProfile, clock: Clock) -> AutopilotPort | None:
    if not cfg.autopilot:
        return None
    raise ValueError("the autopilot link is not available in this build")


def build_node(cfg: NodeConfig, clock: Clock) -> NodeRuntime:
    profile = resolve_profile(cfg)
    autopilot = open_autopilot(cfg, profile, clock)
    log.info(
        "node %d (%s, %s) starting", profile.vehicle_id, profile.model, profile.vehicle_type.name
    )
    return NodeRuntime(cfg, profile, clock, autopilot)
