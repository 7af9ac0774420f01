"""Voting: time to agreement, the 200 lossy trials, votes on the radio.

Simulated time throughout (the ballots are pure cores): `agree_ms` is from the mission
reaching every voter to the last voter's decision, on a LAN-like bus (1-10 ms per
message, seeded loss), median and worst over 20 seeds; `agree_ms_radio_6` is the same
for six gateways on the emulated TDM channel (XTend 115.2 kbps, 200 ms cycle, statuses
at 5 Hz alongside, votes on the VOTE topic's radio policy, compared with the same votes
not acknowledged: `radio_6_policy`). `retasking_fastfleet`: the paper's experiment
in FastFleet, from a payload's target report to the vote decided, to the winners flying
the target mission and to the others flying their replanned shares (simulated s, with
planning taking no simulated time: what planning takes is measured apart, as the wall
time of the plan jobs on this machine, `*_plan_wall_s_max`)."""

from __future__ import annotations

import statistics

from radio_gateway.core.airtime import LinkTiming
from radio_gateway.core.frame import MAX_MESSAGE_BYTES, MAX_RECORD_VALUE
from radio_gateway.core.outbox import OutMessage
from radio_gateway.core.slots import TdmConfig
from swarm_node.ballot_fleet import BallotFleet, lossy_trial
from swarm_node.core.mission.voting import Ballot, Decided, SendVote
from swarm_proto import VehicleStatus, Vote, VoteScore, radio
from swarm_proto.topics import STATUS, VOTE, key_of
from swarm_sim.radio_channel.harness import Fleet
from swarm_sim.radio_channel.model import ChannelParams

SEEDS = 20
MID = 7


def _scores(n: int, seed: int) -> dict[int, float]:
    import random

    r = random.Random(seed)
    return {v: round(r.random(), 3) for v in range(1, n + 1)}


def agree_lan(n: int, loss: float) -> dict[str, float]:
    times, msgs = [], []
    for seed in range(SEEDS):
        f = BallotFleet(_scores(n, seed), 2, seed=seed, loss=loss)
        res = f.run()
        assert res.problems(f.electorate) == [] and res.agree_s is not None
        times.append(res.agree_s * 1000)
        msgs.append(res.messages / n)
    return {
        "median": round(statistics.median(times), 1),
        "max": round(max(times), 1),
        "votes_sent_per_voter": round(statistics.median(msgs), 1),
    }


def lossy_trials(count: int = 200) -> dict[str, int]:
    double = left_out = undecided = disagree = deaths = lates = 0
    for seed in range(count):
        f, res = lossy_trial(seed, "radio" if seed % 4 == 0 else "lan")
        deaths += bool(f.death_s)
        lates += any(f.start_s.values())
        for p in res.problems(f.electorate):
            double += "assigned twice" in p
            left_out += "left out" in p
            undecided += "did not decide" in p
            disagree += "disagree" in p
    return {
        "trials": count,
        "double_assignments": double,
        "left_out": left_out,
        "undecided": undecided,
        "disagreements": disagree,
        "trials_with_a_voter_dying": deaths,
        "trials_with_late_joiners": lates,
    }


def _out(msg: VehicleStatus | Vote) -> OutMessage:
    topic = STATUS if isinstance(msg, VehicleStatus) else VOTE
    p = topic.radio
    return OutMessage(
        key_of("default", msg),
        radio.encode(msg),
        int(p.klass),
        p.latest_only,
        p.acked,
        p.max_rate_hz,
    )


def agree_radio(n: int = 6, seed: int = 1, loss: float = 0.0) -> dict[str, float]:
    """One vote round for n gateways on the emulated TDM channel."""
    tdm = TdmConfig(guard_s=0.002)
    f = Fleet(
        ChannelParams(loss=loss, seed=seed),
        LinkTiming(),
        tdm,
        bytes(range(32)),
        max_nodes=n + 2,
        seed=seed,
    )
    for vid in range(1, n + 1):

        def producer(t: float, vid: int = vid) -> list[OutMessage]:
            s = VehicleStatus(
                vehicle_id=vid,
                time_unix_s=t,
                lat_deg=37.41,
                lon_deg=-5.98,
                alt_msl_m=110.0,
                alt_rel_m=100.0,
                battery_pct=80,
            )
            return [_out(s)]

        f.add(vid, producer=producer, initial_members=tuple(range(1, n + 1)))
    f.run(f.t + 3.0)  # slot table up, statuses flowing
    t0 = f.t
    scores = _scores(n, seed)
    ballots = {v: Ballot(MID, v, frozenset(scores), 2, scores[v], t0) for v in scores}
    decided: dict[int, float] = {}
    seen = len(f.deliveries)
    votes_on_air = 0

    def act(vid: int, outs: list) -> None:
        nonlocal votes_on_air
        for o in outs:
            if isinstance(o, SendVote):
                votes_on_air += 1
                f.node(vid).submit(_out(o.vote), f.t)
            elif isinstance(o, Decided):
                decided.setdefault(vid, f.t)

    while f.t < t0 + 30.0 and not all(b.done for b in ballots.values()):
        due = [d for b in ballots.values() if (d := b.next_deadline()) is not None]
        f.run(min([f.t + 0.02, *due]))
        for _, dst, _, data in f.deliveries[seen:]:
            if radio.peek_type(data) is Vote:
                v = radio.decode(data, now_unix_s=f.t)
                assert isinstance(v, Vote)
                act(dst, ballots[dst].handle(v, f.t))
        seen = len(f.deliveries)
        for vid, b in ballots.items():
            d = b.next_deadline()
            if d is not None and d <= f.t:
                act(vid, b.on_timer(f.t))
    winners = {b.outcome.winners for b in ballots.values() if b.outcome is not None}
    assert len(decided) == n and len(winners) == 1, (decided, winners)
    return {
        "agree_ms": round((max(decided.values()) - t0) * 1000, 1),
        "votes_sent": votes_on_air,
        "collisions": f.model.counts["collisions"],
    }


def radio_policies(seeds: int = 10) -> dict[str, dict[str, float]]:
    """The VOTE topic's radio policy (CONTROL, acknowledged) against not acknowledged:
    the ballot re-sends on its own, so is the gateway's retransmission worth its air?"""
    import msgspec

    from swarm_proto.topics import RadioPolicy

    global VOTE
    chosen = VOTE
    out: dict[str, dict[str, float]] = {}
    try:
        for name, policy in (
            ("acked", chosen.radio),
            ("not_acked", RadioPolicy(True, chosen.radio.klass, acked=False)),
        ):
            VOTE = msgspec.structs.replace(chosen, radio=policy)
            for loss in (0.0, 0.2):
                ms = [agree_radio(6, seed=s, loss=loss)["agree_ms"] for s in range(1, seeds + 1)]
                out.setdefault(name, {})[f"loss_{round(loss * 100)}_median_ms"] = round(
                    statistics.median(ms), 1
                )
    finally:
        VOTE = chosen
    return out


def node_level() -> dict[str, dict[str, object]]:
    """The paper's re-tasking in FastFleet (real MAVLink bytes, simulated time): a
    payload reports a person during a VTOL survey, 2 vehicles are voted to it."""
    import time

    import swarm_sim.fast_fleet as ff
    from swarm_node.core.mission.share import PlanOutcome, PlanRequest
    from swarm_node.database import seed_fleet
    from swarm_sim.retasking import retasking

    profiles = {p.vehicle_id: p for p in seed_fleet()}
    out: dict[str, dict[str, object]] = {}
    real_run_plan = ff.run_plan
    took: list[tuple[int, bool, float]] = []  # (mission id, replan?, wall s) per plan job

    def timed(req: PlanRequest) -> PlanOutcome:
        t0 = time.perf_counter()
        try:
            return real_run_plan(req)
        finally:
            took.append((req.mission.mission_id, req.base is not None, time.perf_counter() - t0))

    ff.run_plan = timed  # FastFleet plans inline in no simulated time: measure the wall time
    try:
        for name, members, kw in (
            ("vtol_3", (1, 2, 3), dict(source=2, at_progress=0.05, half_m=200.0)),
            ("vtol_6", (1, 2, 3, 4, 5, 6), dict(source=3, at_progress=0.3, half_m=350.0)),
        ):
            took.clear()
            r = retasking(profiles, members, to_the_end=False, **kw)  # type: ignore[arg-type]
            target = [s for mid, _, s in took if mid == r.mission_id]
            replans = [s for mid, again, s in took if mid != r.mission_id and again]
            out[name] = {
                "report_to_decided_s": round(r.report_to_decided_s, 2),
                "report_to_winners_flying_s": round(r.report_to_flying_s, 2),
                "report_to_others_replanned_s": round(r.report_to_replanned_s, 2),
                "target_plan_wall_s_max": round(max(target, default=0.0), 2),
                "area_replan_wall_s_max": round(max(replans, default=0.0), 2),
                "winners": list(r.winners),
                "same_replan_everywhere": r.same_plan,
            }
    finally:
        ff.run_plan = real_run_plan
    return out


def vote_bytes(n: int) -> int:
    v = Vote(
        2**32 - 1,
        65534,
        tuple(VoteScore(65534 - i, 0.1234) for i in range(n)),
        round=255,
        members_hash=0xFFFF,
        committed=True,
    )
    return len(radio.encode(v))


def run() -> dict:
    agree = {
        f"n_{n}": {f"loss_{round(loss * 100)}": agree_lan(n, loss) for loss in (0.0, 0.2)}
        for n in (6, 20, 50)
    }
    radio6 = agree_radio(6)
    lossy_radio = [agree_radio(6, seed=s, loss=0.2)["agree_ms"] for s in range(1, 11)]
    return {
        "agree_ms": agree,
        **lossy_trials(200),
        "agree_ms_radio_6": radio6["agree_ms"],
        "radio_6": radio6,
        "agree_ms_radio_6_loss_20": {
            "median": round(statistics.median(lossy_radio), 1),
            "max": max(lossy_radio),
            "seeds": len(lossy_radio),
        },
        "radio_6_policy": radio_policies(),
        "retasking_fastfleet": node_level(),
        "vote_radio_bytes": {"n_6": vote_bytes(6), "n_20": vote_bytes(20), "n_50": vote_bytes(50)},
        "radio_limits_bytes": {"unfragmented": MAX_RECORD_VALUE, "message": MAX_MESSAGE_BYTES},
    }
