"""Builds a NodeRuntime from a NodeConfig: identity and parameters, the autopilot link,
the Zenoh session."""

from __future__ import annotations

import logging
from collections.abc import Callable

from swarm_proto import Clock

from ..core.profile import VehicleProfile
from ..database import SwarmDatabase
from ..database.errors import SwarmDbError
from .config import NodeConfig, profile_from_config
from .node import AutopilotPort, NodeRuntime

log = logging.getLogger("swarm_node")


def resolve_profile(cfg: NodeConfig, db: SwarmDatabase | None) -> VehicleProfile:
    """The node's identity and parameters: from the swarm database (the default), or
    from the config's [profile] table for a node run without one."""
    if cfg.profile is not None or db is None:
        return profile_from_config(cfg)
    try:
        return db.vehicle_profile(vehicle_id=cfg.node_id)
    except SwarmDbError as exc:
        raise ValueError(f"node {cfg.node_id}: {exc}") from exc


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
        settings=LinkSettings(link_timeout_s=cfg.link_timeout_s),
        name=f"autopilot-{profile.vehicle_id}",
    )
    link.start()
    return link


def open_database(cfg: NodeConfig) -> SwarmDatabase | None:
    """The swarm database (`db` in the config, else $BANDADA_DB, else the per-user file,
    created with the seed data when missing); None when the config carries a [profile]."""
    if cfg.profile is not None:
        return None
    try:
        return SwarmDatabase.open(cfg.db)
    except SwarmDbError as exc:
        raise ValueError(str(exc)) from exc


def build_node(cfg: NodeConfig, clock: Clock) -> NodeRuntime:
    if cfg.autopilot:
        from .mavlink_transport import check_address

        check_address(cfg.autopilot)  # ValueError before anything opens: exit 2
    db = open_database(cfg)
    profile = resolve_profile(cfg, db)
    log.info(
        "node %d (%s %s, %s) starting",
        profile.vehicle_id,
        profile.model,
        profile.user_id,
        profile.vehicle_type.name,
    )
    node = NodeRuntime(cfg, profile, clock, database=db)
    link = open_autopilot(cfg, profile, clock, on_event=node.on_autopilot_event)
    if link is not None:
        node.autopilot = link
    return node
