"""The paper's InfoRecoveryManager: `gcs save FILE` stores the swarm's state (the base,
the zones in force, the missions in force with who flies them, each vehicle's home),
`gcs load FILE` sends a prepared set back (the base, then the zones, then the
missions), every step's answers accounted for. The file is JSON (`SwarmState`), made
by `gcs save` or by hand; `gcs plot` draws it."""

from __future__ import annotations

import time
from collections import Counter
from pathlib import Path

import msgspec
import typer

from swarm_proto import (
    CommandArgs,
    CommandKind,
    FsmState,
    GeoPoint,
    Mission,
    NoFlyZone,
    VehicleType,
)

from .answers import progress, report
from .common import Link, ask, console, selector_from, timeout_option
from .ground import MISSION_TIMEOUT_S, GroundStation, new_seq
from .options import AllOption, FleetOption, IdsOption, JsonOption, YesOption, checked

app = typer.Typer()  # save, load: app.py puts them at the top level

FORMAT = "bandada-swarm-state"


class VehicleState(msgspec.Struct, frozen=True):
    vehicle_id: int
    vehicle_type: VehicleType = VehicleType.OTHER
    model: str = ""
    home: GeoPoint | None = None
    base: GeoPoint | None = None
    fleet_id: int = 0
    mission_id: int = 0
    fsm_state: FsmState = FsmState.INACTIVE
    position: GeoPoint | None = None


class SwarmState(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """What `gcs save` writes and `gcs load` sends."""

    format: str = FORMAT
    version: int = 1
    saved_unix_s: float = 0.0
    swarm: str = "default"
    base: GeoPoint | None = None
    zones: list[NoFlyZone] = []
    missions: list[Mission] = []
    vehicles: list[VehicleState] = []

    def members(self, mission_id: int) -> list[int]:
        return sorted(v.vehicle_id for v in self.vehicles if v.mission_id == mission_id)


class StateFileError(ValueError):
    pass


def read_state(path: Path) -> SwarmState:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise StateFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        state = msgspec.json.decode(raw, type=SwarmState)
    except (msgspec.DecodeError, msgspec.ValidationError, ValueError) as exc:
        raise StateFileError(
            f"{path}: not a swarm state file: {' '.join(str(exc).split())}"
        ) from None
    if state.format != FORMAT:
        raise StateFileError(f"{path}: format {state.format!r}, expected {FORMAT!r}")
    return state


def collect(gs: GroundStation, timeout_s: float = 2.0) -> tuple[SwarmState, list[str]]:
    """The swarm's state as the vehicles tell it now, and what did not agree."""
    alive = gs.discover()
    if not alive:  # a slow start on a loaded host: the 1 Hz VehicleInfo says who is there
        gs.wait_for(lambda v: bool(v.info), max(timeout_s, 3.0))
    alive |= set(gs.snapshot().vehicle_ids())  # and every vehicle heard meanwhile (5 Hz)
    gs.wait_for(lambda v: all(i in v.info for i in alive), 2.5)  # VehicleInfo: 1 Hz
    view = gs.snapshot()
    warnings: list[str] = []
    vehicles = []
    for vid in view.vehicle_ids():
        info, st = view.info.get(vid), view.status.get(vid)
        if info is None:
            continue
        pos = GeoPoint(st.lat_deg, st.lon_deg, st.alt_msl_m) if st else None
        vehicles.append(
            VehicleState(
                vid,
                info.vehicle_type,
                info.model,
                info.home,
                info.base,
                info.fleet_id,
                info.mission_id,
                info.fsm_state,
                pos,
            )
        )
    bases = Counter(v.base for v in vehicles if v.base is not None)
    base = bases.most_common(1)[0][0] if bases else None
    if len(bases) > 1:
        warnings.append(
            "the vehicles disagree on the base: "
            + "; ".join(f"{b.lat_deg:.6f},{b.lon_deg:.6f} by {n}" for b, n in bases.items())
        )
    now = time.time()
    zones: dict[int, NoFlyZone] = {}
    for zs in gs.all_zones(timeout_s).values():
        for zid, z in zs.items():
            if z.in_force(now) and (
                zid not in zones or z.valid_from_unix_s > zones[zid].valid_from_unix_s
            ):
                zones[zid] = z
    in_force = {v.mission_id for v in vehicles if v.mission_id}
    missions: dict[int, Mission] = {}
    for ms in gs.missions_held(timeout_s).values():
        for mid, m in ms.items():
            if mid in in_force:
                missions.setdefault(mid, m)
    for mid in sorted(in_force - set(missions)):
        warnings.append(f"mission {mid} is flown but no vehicle served it (missions queryable)")
    state = SwarmState(
        FORMAT,
        1,
        round(now, 3),
        gs.swarm,
        base,
        sorted(zones.values(), key=lambda z: z.zone_id),
        sorted(missions.values(), key=lambda m: m.mission_id),
        vehicles,
    )
    return state, warnings


@app.command()
def save(
    ctx: typer.Context,
    file: Path = typer.Argument(..., dir_okay=False, help="the state file to write (JSON)"),
    timeout: float = typer.Option(2.0, help="seconds to wait for the vehicles' answers"),
) -> None:
    """Save the swarm's state: the base, the zones in force, the missions in force (and
    who flies them), each vehicle's home and position. `gcs load FILE` sends it back;
    `gcs plot --state FILE` draws it. Exit 1 if no vehicle answered.

    Example: gcs save before-landing.json
    """
    timeout_option(timeout)
    link: Link = ctx.obj
    with link.open() as gs:
        state, warnings = collect(gs, timeout)
    for w in warnings:
        console.print(f"[yellow]{w}[/]")
    if not state.vehicles:
        console.print("[red]no vehicle heard: nothing saved[/]")
        raise typer.Exit(1)
    try:
        file.write_bytes(msgspec.json.format(msgspec.json.encode(state), indent=2) + b"\n")
    except OSError as exc:
        raise typer.BadParameter(f"{file}: cannot write: {exc.strerror or exc}") from None
    b = state.base
    console.print(
        f"saved {file}: base {f'{b.lat_deg:.6f},{b.lon_deg:.6f}' if b else 'not set'}, "
        f"{len(state.zones)} zone(s), {len(state.missions)} mission(s) in force, "
        f"{len(state.vehicles)} vehicle(s)"
    )


@app.command()
def load(
    ctx: typer.Context,
    file: Path = typer.Argument(..., dir_okay=False, help="a state file (gcs save, or by hand)"),
    ids: IdsOption = [],  # noqa: B006
    fleet: FleetOption = None,
    all_: AllOption = False,
    keep_ids: bool = typer.Option(
        False,
        "--keep-ids",
        help="send the missions with their ids "
        "(default: fresh ids, so vehicles that answered them before "
        "take them again)",
    ),
    timeout: float = typer.Option(10.0, help="seconds to wait for each step's answers"),
    yes: YesOption = False,
    as_json: JsonOption = False,
) -> None:
    """Send a prepared set: the base (set-base to --id/--fleet/--all, default every
    vehicle), then every zone, then every mission (each to its own selection), each
    step's answers shown. The whole file is checked before anything is sent; missions
    are sent only when the base and every zone were accepted. Exit 1 on any refusal or
    silence.

    Example: gcs load prepared.json --yes
    """
    timeout_option(timeout)
    try:
        state = read_state(file)
    except StateFileError as exc:
        raise typer.BadParameter(str(exc), param_hint="FILE") from None
    link: Link = ctx.obj
    sel = selector_from(ids, fleet, 0, "", all_)
    zones = [checked(msgspec.structs.replace(z, issuer_id=link.gcs_id)) for z in state.zones]
    missions: list[Mission] = []
    for m in state.missions:
        mid = m.mission_id if keep_ids else (new_seq() or 1) + len(missions)
        missions.append(
            checked(
                msgspec.structs.replace(
                    m, mission_id=mid, issuer_id=link.gcs_id, time_unix_s=time.time()
                )
            )
        )
    if state.base is not None:
        checked(state.base)
    failed = False
    with link.open() as gs:
        if missions:
            ask(gs, f"load {len(missions)} mission(s) from {file.name}", sel, yes)
        if state.base is not None:
            with progress(not as_json) as show:
                out = gs.send_command(
                    CommandKind.SET_BASE,
                    sel,
                    CommandArgs(point=state.base),
                    timeout_s=timeout,
                    progress=show,
                )
            failed |= _step(out, as_json)
        for z in zones:
            with progress(not as_json) as show:
                out = gs.send_zone(z, sel, timeout_s=timeout, progress=show)
            failed |= _step(out, as_json)
        if missions and failed:
            console.print("[red]missions not sent: the base or a zone was not accepted by all[/]")
        elif missions:
            for m in missions:
                with progress(not as_json) as show:
                    # the fleet answers once its plan is made
                    wait = max(timeout, MISSION_TIMEOUT_S)
                    out = gs.send_mission(m, timeout_s=wait, progress=show)
                failed |= _step(out, as_json)
    if failed:
        raise typer.Exit(1)


def _step(out: object, as_json: bool) -> bool:
    """Show one step's outcome; True when it failed."""
    try:
        report(out, console, as_json=as_json)  # type: ignore[arg-type]
    except typer.Exit:
        return True
    return False
