"""Voting and re-tasking from the ground: `gcs target report` publishes a
target as a payload or the operator would, `gcs vote MISSION` shows a vote (who took
part, every score, who went), and `gcs mission ... --count N` shows its vote after the
acks (`VoteWatch`, hooked in cli.py).

What a vote decided is read from what the vehicles publish: their Votes (the last ones
carry the whole table and `committed`), the INFO alert each winner raises ("chosen for
mission N, score S") and the ranking the vehicles use (`swarm_node.core.mission.voting.rank`) when the
quantity is known.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

import typer
from rich.console import Console
from rich.table import Table

from swarm_node.core.mission.tasking import target_mission_id
from swarm_node.core.mission.voting import rank, score_key
from swarm_proto import Ack, AckRef, GeoPoint, TargetReport, TargetSource, Vote, validate
from swarm_proto.errors import ProtoError
from swarm_proto.topics import ACK, VOTE

from .common import parse_point
from .ground import FleetView, GroundStation
from .render import ack_table

console = Console()
app = typer.Typer(
    help="Targets: report one (re-tasking by the swarm's rules).", no_args_is_help=True
)


# --------------------------------------------------------------------------- votes


class VoteWatch:
    """Collects the Votes heard on a ground station's session (subscribe before the
    mission goes out: the first votes follow its arrival within milliseconds)."""

    def __init__(self, gs: GroundStation) -> None:
        self.gs = gs
        self.votes: dict[int, dict[int, Vote]] = {}  # mission -> voter -> its latest vote
        self.acks: dict[int, dict[int, Ack]] = {}  # mission -> vehicle -> its first answer
        self._cond = threading.Condition()
        gs.bus.subscribe(VOTE, self._on_vote)
        gs.bus.subscribe(ACK, self._on_ack)  # whoever issued the mission (a vehicle's report)

    def _on_vote(self, vote: Vote, key: str) -> None:
        with self._cond:
            mine = self.votes.setdefault(vote.mission_id, {})
            old = mine.get(vote.voter_id)
            if old is None or vote.committed or not old.committed:
                mine[vote.voter_id] = vote
            self._cond.notify_all()

    def _on_ack(self, ack: Ack, key: str) -> None:
        if ack.ref != AckRef.MISSION:
            return
        with self._cond:
            self.acks.setdefault(ack.ref_id, {}).setdefault(ack.vehicle_id, ack)
            self._cond.notify_all()

    def answers(self, mission_id: int) -> dict[int, Ack]:
        with self._cond:
            return dict(self.acks.get(mission_id, {}))

    def of(self, mission_id: int) -> dict[int, Vote]:
        with self._cond:
            return dict(self.votes.get(mission_id, {}))

    def wait(self, mission_id: int, voters: set[int], timeout_s: float) -> dict[int, Vote]:
        """Until every one of `voters` has voted `committed` (or the timeout)."""
        end = time.monotonic() + max(0.0, timeout_s)
        with self._cond:
            while True:
                got = self.votes.get(mission_id, {})
                if voters and all(v in got and got[v].committed for v in voters):
                    break
                left = end - time.monotonic()
                if left <= 0:
                    break
                self._cond.wait(min(left, 0.1))
            return dict(self.votes.get(mission_id, {}))


@dataclass
class VoteResult:
    mission_id: int
    scores: dict[int, float]  # the table the vehicles decided on (or the largest heard)
    decided: bool  # some voter said committed
    winners: tuple[int, ...] | None  # by the vehicles' ranking, when the quantity is known
    went: set[int] = field(default_factory=set)  # vehicles that said they were chosen
    voters: set[int] = field(default_factory=set)


def result_of(
    mission_id: int, votes: dict[int, Vote], quantity: int | None, went: set[int]
) -> VoteResult:
    committed = [v for v in votes.values() if v.committed]
    pool = committed or list(votes.values())
    best = max(pool, key=lambda v: len(v.scores), default=None)
    scores = {s.vehicle_id: s.score for s in best.scores} if best else {}
    winners = None
    if quantity and scores:
        winners = rank({v: score_key(s) for v, s in scores.items()}, quantity)
    return VoteResult(mission_id, scores, bool(committed), winners, went, set(votes))


def vote_table(r: VoteResult) -> Table:
    goes = set(r.winners) if r.winners is not None else r.went
    order = sorted(r.scores, key=lambda v: (-score_key(r.scores[v]), v))
    state = "decided" if r.decided else "not decided yet"
    t = Table(title=f"mission {r.mission_id}: vote {state}")
    for col in ("vehicle", "score", "decision", "said chosen"):
        t.add_column(col, justify="right" if col != "decision" else "left")
    for vid in order:
        decision = "goes" if vid in goes else "stays"
        t.add_row(str(vid), f"{r.scores[vid]:.4f}", decision, "yes" if vid in r.went else "")
    for vid in sorted(r.voters - set(r.scores)):
        t.add_row(str(vid), "-", "no score", "")
    return t


def chosen(view: FleetView, mission_id: int) -> set[int]:
    """Vehicles that said they were chosen (each winner raises an INFO alert)."""
    said = f"chosen for mission {mission_id},"
    return {a.vehicle_id for a in view.alerts if a.text.startswith(said)}


def show_vote(
    gs: GroundStation,
    watch: VoteWatch,
    mission_id: int,
    voters: set[int],
    quantity: int | None,
    wait_s: float,
) -> VoteResult:
    """Wait for the vote among `voters` and print it (every score, who goes); then
    give the winners a second to show the mission in their VehicleInfo."""
    votes = watch.wait(mission_id, voters, wait_s)
    if votes:  # (the predicate runs under the station's lock: it reads the view given)
        gs.wait_for(lambda view: len(chosen(view, mission_id)) >= (quantity or 1), 2.0)
    r = result_of(mission_id, watch.of(mission_id), quantity, chosen(gs.snapshot(), mission_id))
    if not r.voters:
        console.print(f"[yellow]mission {mission_id}: no vote heard[/]")
        return r
    console.print(vote_table(r))
    if r.winners is not None:
        console.print(f"winners: {', '.join(map(str, r.winners))}")
    return r


def vote(
    ctx: typer.Context,
    mission_id: int = typer.Argument(..., help="the mission voted for"),
    count: int | None = typer.Option(None, help="how many it asked for (ranks the table)"),
    wait: float = typer.Option(5.0, help="seconds to listen for the votes"),
) -> None:
    """Show a vote: every vehicle's score and who goes (from the votes the vehicles
    re-send for a few seconds after deciding, and the winners' status). A vote over
    before this listened is read from the vehicles: who flies the mission (their
    VehicleInfo) and who holds it (their missions queryable); its scores are gone.

    Example: gcs vote 4242 --count 2 --wait 5
    """
    if not (wait >= 0.0 and wait < 3600.0):
        raise typer.BadParameter("--wait must be in [0, 3600) s", param_hint="--wait")
    if count is not None and not 1 <= count <= 255:
        raise typer.BadParameter("--count must be 1..255", param_hint="--count")
    with ctx.obj.open() as gs:
        watch = VoteWatch(gs)
        time.sleep(wait)
        if not watch.of(mission_id):  # over before we listened: what the vehicles hold
            held = gs.missions_held(2.0)
            after = decided_after(gs.snapshot(), held, mission_id)
            console.print(after.text(), highlight=False)
            if not after.flown_by:
                raise typer.Exit(1)
            return
        r = show_vote(gs, watch, mission_id, set(watch.of(mission_id)), count, 0.0)
    if not r.decided:
        raise typer.Exit(1)


@dataclass(frozen=True)
class After:
    """A vote read after it was over: who flies the mission (their VehicleInfo), who
    holds it (their missions queryable: the candidates that accepted it)."""

    mission_id: int
    flown_by: tuple[int, ...]
    held_by: tuple[int, ...]

    def text(self) -> str:
        m = self.mission_id
        held = f"; held by {', '.join(map(str, self.held_by))}" if self.held_by else ""
        if not self.flown_by:
            return f"mission {m}: no vote heard and no vehicle flies it{held}"
        return (
            f"mission {m}: decided before this listened (the votes are re-sent for a few "
            f"seconds only, the scores are gone): flown by {', '.join(map(str, self.flown_by))} "
            f"(their VehicleInfo){held}"
        )


def decided_after(view: FleetView, held: dict[int, dict[int, object]], mission_id: int) -> After:
    """The outcome of a vote over before `gcs vote` listened, from what the vehicles
    publish and hold: the winners fly the mission (VehicleInfo.mission_id)."""
    flown = tuple(sorted(v for v, i in view.info.items() if i.mission_id == mission_id))
    holding = tuple(sorted(v for v, ms in held.items() if mission_id in ms))
    return After(mission_id, flown, holding)


# --------------------------------------------------------------------------- targets


@app.command("report")
def report(
    ctx: typer.Context,
    point: str = typer.Option(..., help="LAT,LON of the target"),
    target_class: str = typer.Option("person", "--class", help="what it is (a detection class)"),
    confidence: float = typer.Option(1.0, help="0..1 (the re-tasking rules' threshold)"),
    target_id: int = typer.Option(0, help="the report's id (default: a fresh one)"),
    as_vehicle: int = typer.Option(
        0, help="report it as this vehicle's payload detector (default: the operator)"
    ),
    timeout: float = typer.Option(5.0, help="seconds to wait for the vehicles' answers"),
    vote_wait: float = typer.Option(15.0, help="seconds to wait for the vote"),
) -> None:
    """Report a target. The vehicles apply the swarm's re-tasking rules (the database's
    `target re-tasking` module: vehicles per class, minimum confidence) and vote who
    flies the target mission; its id is derived from the report. Prints every
    vehicle's answer and the vote.

    Example: gcs target report --point 37.4125,-5.9889 --class person --confidence 0.9
    """
    lat, lon = parse_point(point)
    if not (confidence >= 0.0 and confidence <= 1.0):
        raise typer.BadParameter("--confidence must be in [0, 1]", param_hint="--confidence")
    for name, v in (("--timeout", timeout), ("--vote-wait", vote_wait)):
        if not (v >= 0.0 and v < 3600.0):
            raise typer.BadParameter(f"{name} must be in [0, 3600) s", param_hint=name)
    if not 0 <= target_id <= 2**32 - 1 or not 0 <= as_vehicle <= 65534:
        raise typer.BadParameter("--target-id is a uint32, --as-vehicle a vehicle id")
    tid = target_id or int(time.time() * 1000) % (1 << 32)
    try:
        msg = TargetReport(
            tid,
            as_vehicle or ctx.obj.gcs_id,
            TargetSource.PAYLOAD if as_vehicle else TargetSource.OPERATOR,
            time.time(),
            GeoPoint(lat, lon, 0.0),
            target_class[:48],
            confidence,
        )
        validate(msg)
    except (ValueError, TypeError, ProtoError) as exc:
        raise typer.BadParameter(str(exc)) from exc
    mid = target_mission_id(msg.source_id, msg.target_id)
    with ctx.obj.open() as gs:
        watch = VoteWatch(gs)
        vehicles = set(gs.discover())
        console.print(f"target {tid} reported: mission {mid} if the rules ask for vehicles")
        end = time.monotonic() + timeout
        while True:  # repeated until answered: the vehicles take a repeat as the same target
            gs.bus.publish(msg)
            gs.wait_for(lambda v: vehicles <= set(watch.answers(mid)), min(1.0, timeout))
            if vehicles <= set(watch.answers(mid)) or time.monotonic() >= end:
                break
        acks = list(watch.answers(mid).values())
        if not acks:
            console.print(
                f"[yellow]no vehicle took it up (no re-tasking rule for {target_class!r}, "
                "or below its confidence)[/]"
            )
            raise typer.Exit(1)
        console.print(ack_table(acks, f"target mission {mid}"))
        voters = {a.vehicle_id for a in acks if a.accepted}
        if not voters:
            console.print(f"[yellow]mission {mid}: no candidate[/]")
            raise typer.Exit(1)
        r = show_vote(gs, watch, mid, voters, None, vote_wait)
    if not r.decided:
        raise typer.Exit(1)
