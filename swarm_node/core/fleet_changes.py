"""What the node does when its fleet changes by a vote, a target report, a join or a
swap: it carries out what `mission/tasking.py` (QUANTITY missions, the
ballot, re-tasking) and `swarm/regroup.py` (add and swap) return, with the node's own
parts: acks, the roster, the state machine's events, the mission manager. NodeCore
routes to it (node.py: `Mission` of a QUANTITY selector, `Vote`, `TargetReport`,
`PlanLineage`, JOIN_MISSION and SWAP_MISSION); it reads and changes the node's state
as the node's own methods would (a collaborator kept apart so node.py stays a router).

Pure: no I/O, `now` passed in.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, assert_never

from swarm_proto import (
    Ack,
    AckReason,
    AckRef,
    Alert,
    AlertCode,
    Command,
    CommandKind,
    FsmState,
    LatLon,
    LineageStep,
    Mission,
    MissionState,
    SelectorKind,
    Severity,
)

from . import state_machine as fsm
from .commands import answer_key, check_mission, plan_command
from .mission.scoring import Candidate
from .mission.tasking import Derived, Elected, Standing, TaskingOutput, VoteFailed
from .mission_manager import with_defaults
from .outputs import ModuleOutput, Note, Publish
from .swarm.regroup import Lineage, handed_lineage

if TYPE_CHECKING:
    from .node import NodeCore


class FleetChanges:
    def __init__(self, node: NodeCore) -> None:
        self.node = node

    # ------------------------------------------------------------------ tasking
    def on_quantity(self, mission: Mission, now: float) -> list[ModuleOutput]:
        """A QUANTITY mission, sent or derived from a target report: are we a candidate
        (the acceptance checks, then tasking's), then the vote: a flying fleet votes at
        once, idle vehicles synchronise in PLAN first (mission/tasking.py)."""
        repeat = self.node._repeat(mission)
        if repeat is not None:
            return repeat
        reason, text = check_mission(mission, self.node.view()), ""
        st: Standing | None = None
        if reason == AckReason.OK:
            mission = with_defaults(
                mission, self.node.mission_defaults.get(mission.mission_type, {})
            )
            st = self.standing()
            reason, text = self.node.tasking.answer(mission, st)
        ok = reason == AckReason.OK
        ack = Ack(
            self.node.self_id,
            mission.issuer_id,
            AckRef.MISSION,
            mission.mission_id,
            ok,
            reason,
            text[:64],
        )
        out: list[ModuleOutput] = self.node._answer([ack]) if ok else [Publish(ack)]
        if not ok or st is None:
            return out
        if st.flying is not None:
            electorate, lost = self.node.tasking.electorate(mission, st)
            start = self.node.tasking.start(
                mission, electorate, lost, st.me, now, home=st.flying, lead=self.lead(mission)
            )
            return out + self.tasked(start, now)
        self.node.missions[mission.mission_id] = mission
        self.node.fsm.post(fsm.NewMission(mission.mission_id))
        return out

    def candidate(self) -> Candidate:
        ap = self.node.autopilot
        at = None if ap.lat_deg is None or ap.lon_deg is None else LatLon(ap.lat_deg, ap.lon_deg)
        battery = float(ap.battery_pct) if ap.battery_pct >= 0 else None
        return Candidate.of(self.node.profile, at, battery)

    def lead(self, mission: Mission) -> LatLon | None:
        peer = self.node.members.peers.get(mission.params.lead_vehicle_id)
        st = peer.status if peer is not None else None
        return LatLon(st.lat_deg, st.lon_deg) if st is not None else None

    def standing(self) -> Standing:
        r, f = self.node.roster, self.node.fsm
        flying, replanning = None, False
        if (
            r.frozen
            and r.mission_id is not None
            and r.mission_id > 0
            and f.mission_id == r.mission_id
        ):
            flying = r.mission_id
            replanning = f.state != FsmState.GO_MISSION or self.node.manager.mission_state not in (
                MissionState.PREMISSION,
                MissionState.MISSION,
            )
        present = {
            v: p
            for v, p in self.node.members.peers.items()
            if p.present and not p.is_ground_station
        }
        return Standing(
            self.node.self_id,
            self.node.fleet_id,
            self.candidate(),
            idle=f.state == FsmState.GO_MISSION and f.mission_id is None and self.node.active,
            flying=flying,
            replanning=replanning,
            fleet=r.planned,
            away=frozenset(
                v
                for v in r.planned
                if v not in r.flying or (v != self.node.self_id and v not in present)
            ),
            peer_fleets={v: p.fleet_id for v, p in present.items()},
            peer_missions={
                v: p.mission_id
                for v, p in present.items()
                if p.mission_id > 0 and p.fsm_state in (FsmState.PLAN, FsmState.GO_MISSION)
            },
        )

    def tasked(self, outs: list[TaskingOutput], now: float) -> list[ModuleOutput]:
        out: list[ModuleOutput] = []
        for o in outs:
            match o:
                case Publish() | Note():
                    out.append(o)
                case Derived(mission):
                    self.node.regroup.heard_mission(mission)
                    out += self.on_quantity(mission, now)
                case Elected():
                    out += self.elected(o, now)
                case VoteFailed(mid, home, _reason):
                    if home is None and self.node.fsm.mission_id == mid:
                        self.node.fsm.post(fsm.Unassigned(mid, "vote failed"))
                case _:
                    assert_never(o)
        return out

    def elected(self, e: Elected, now: float) -> list[ModuleOutput]:
        """The vote decided: winners fly the mission as a new fleet (selected by their
        ids); a flying fleet's others lose them ("voted out") and replan; idle vehicles
        not chosen stand down."""
        mid, winners = e.mission.mission_id, e.outcome.winners
        if e.home is None:  # idle vehicles synchronised in PLAN for it
            if self.node.fsm.mission_id != mid or self.node.fsm.state != FsmState.PLAN:
                return []
            if not e.goes:
                self.node.fsm.post(fsm.Unassigned(mid, "not chosen"))
                return []
            self.node.missions[mid] = e.mission
            self.node.roster.elected(winners)
            self.node.manager.elected()
            members, unknown = self.node._members()
            if unknown:
                self.node.fsm.post(
                    fsm.PlanFailed(mid, f"no profile for fleet members {unknown}"[:64])
                )
                return []
            self.node.regroup.founded(e.mission, members)
            return self.node.manager.release(
                e.mission, members, self.node.planning_zones(now), self.node.autopilot, now
            )
        if e.goes:
            if self.node.fsm.mission_id == e.home:
                self.node.missions.pop(e.home, None)  # left for the new mission, not completed
            self.node.missions[mid] = e.mission
            self.node.fsm.post(fsm.NewMission(mid))
            out: list[ModuleOutput] = [
                Note(logging.INFO, f"leaving mission {e.home} for mission {mid}")
            ]
            if not e.outcome.stayers and self.node.self_id == min(winners):
                text = f"mission {e.home} left unfinished: its fleet went to {mid}"
                out.append(
                    Publish(
                        Alert(
                            self.node.self_id,
                            max(0.0, now),
                            Severity.WARNING,
                            AlertCode.MISSION_FAILED,
                            text[:64],
                        )
                    )
                )
            return out
        if self.node.roster.mission_id == e.home:
            return self.node._roster_events(self.node.roster.voted_out(winners))
        return []

    # ------------------------------------------------------------------ add / swap
    def on_regroup(self, cmd: Command, now: float) -> list[ModuleOutput]:
        """JOIN_MISSION / SWAP_MISSION (swarm/regroup.py): the vehicle leaves what it
        flies and joins the other fleet, which takes it in with a replan and tells it how
        its plan came to be; a swap that empties a fleet hands its mission over."""
        if cmd.target.kind == SelectorKind.QUANTITY or not cmd.target.addresses(
            self.node.self_id, self.node.fleet_id
        ):
            plan = plan_command(
                cmd, self.node.view()
            )  # not addressed: no answer; QUANTITY: refused
            return self.node._answer([plan.ack]) if plan is not None and plan.ack else []
        self.node.answers.taken(answer_key(cmd))
        view = self.node.view()
        st = self.standing()
        reason, text, to = AckReason.OK, "", 0
        if view.autopilot.home is None or view.base is None:
            reason = AckReason.HOME_NOT_SET if view.autopilot.home is None else AckReason.NO_BASE
        elif view.fsm_state == FsmState.EMERGENCY:
            reason = AckReason.EMERGENCY
        elif not view.ready or view.fsm_state == FsmState.INACTIVE:
            reason = AckReason.NOT_READY
        elif st.replanning:
            reason, text = AckReason.BUSY, f"replanning mission {st.flying}"
        else:
            reason, text, to = self.node.regroup.answer(cmd, st.flying, st.idle)
        ok = reason == AckReason.OK
        ack = Ack(self.node.self_id, cmd.issuer_id, AckRef.COMMAND, cmd.seq, ok, reason, text[:64])
        out = self.node._answer([ack])
        if not ok:
            return out
        mission = with_defaults(
            self.node.regroup.heard[to],
            self.node.mission_defaults.get(self.node.regroup.heard[to].mission_type, {}),
        )
        if st.flying is not None:
            if cmd.kind == CommandKind.SWAP_MISSION and self.emptied(cmd, st.flying, to):
                out += self.hand_over(st.flying, to)
            self.node.missions.pop(st.flying, None)  # left, not completed
        self.node.missions[to] = mission
        self.node.regroup.joining = to
        self.node.fsm.post(fsm.NewMission(to))
        return [*out, Note(logging.INFO, f"joining mission {to}'s fleet")]

    def emptied(self, cmd: Command, ours: int, theirs: int) -> bool:
        """This swap takes every member of our fleet and none of theirs."""
        named = set(cmd.target.vehicle_ids)
        if not set(self.node.roster.flying) <= named:
            return False
        peers = self.node.members.peers
        return not any(
            v in peers and peers[v].present and peers[v].mission_id == theirs for v in named
        )

    def hand_over(self, ours: int, theirs: int) -> list[ModuleOutput]:
        """Our fleet is emptied: its lineage, with the progress we leave at, goes to the
        fleet of `theirs` (the paper's SENDING_MISSION)."""
        lineage = self.node.regroup.lineages.get(ours)
        if lineage is None:
            return [Note(logging.WARNING, f"mission {ours}: no plan to hand over")]
        last = Lineage(lineage.mission, lineage.first, list(lineage.steps))
        self.node.regroup.replanned(ours, (), self.node._progress_now()[0])  # the hand-over step
        msg = self.node.regroup.lineages[ours].message(
            self.node.self_id, self.node.roster.members_hash, theirs
        )
        self.node.regroup.lineages[ours] = last
        self.node.regroup.on_lineage(msg)  # we go to their fleet: we take it up with them
        return [
            Note(logging.INFO, f"mission {ours}: emptied, handed to mission {theirs}'s fleet"),
            Publish(msg),
        ]

    def take_over_handed(self, ours: int) -> None:
        """Our mission is flown: take up an emptied fleet's mission handed to ours (the
        fleet as the swap left it flies what is left of it), instead of flying home."""
        handed = self.node.regroup.handover(ours)
        if not handed:
            return
        msg = handed_lineage(handed)
        mine = self.node.regroup.lineages.get(ours)
        movers = set(handed)
        adopters: tuple[int, ...] = mine.members if mine else (self.node.self_id,)
        for step in mine.steps if mine else ():
            if movers & set(step.members):
                adopters = step.members
                break
        mid = msg.mission.mission_id
        self.node.regroup.adopting[mid] = (msg, adopters)
        self.node.missions[mid] = msg.mission
        self.node.fsm.post(fsm.NewMission(mid))

    def join(self, mid: int, now: float) -> list[ModuleOutput]:
        """Fly the plan of the fleet we join (or an emptied fleet's, handed to ours),
        made again from its lineage."""
        adopting = self.node.regroup.adopting.pop(mid, None)
        if adopting is not None:
            msg, adopters = adopting
            lineage = Lineage.of(msg)
        else:
            msg, adopters = self.node.regroup.offered[mid], ()
            lineage = self.node.regroup.adopted(msg)
        try:
            replay = lineage.replay(self.node.fleet_profiles, adopters)
        except KeyError as exc:
            self.node.fsm.post(fsm.PlanFailed(mid, f"no profile for fleet member {exc}"[:64]))
            return []
        if adopters:  # the hand-over step is ours now: taken up by the adopters
            lineage.steps[-1] = LineageStep(tuple(adopters), lineage.steps[-1].progress)
            self.node.regroup.lineages[mid] = lineage
        self.node.missions[mid] = msg.mission
        self.node.roster.adopt(mid, lineage.everyone, lineage.members, len(lineage.steps))
        return self.node.manager.release(
            msg.mission,
            replay.first,
            self.node.planning_zones(now),
            self.node.autopilot,
            now,
            lineage=replay,
        )
