"""Plan jobs for in-process harnesses (FastFleet, testing.Fleet): every fleet member
plans the same mission from the same inputs (core/mission/share.py), so a harness that
runs all the members in one process plans each distinct request once.

What a node gets is what the runtime's planner process hands it: the outcome pickled
and unpickled (a copy of its own, never an object shared with another node), with its
own job id. The key is the request without its job id, its members in id order (each
node lists itself first; the planners sort the members by id, `fleet_plan.plan_fleet` and
`FleetPlan.replan`) and its progress in id order, pickled: a request that differs in
anything else (a member's home or profile, a zone, the time, a replan's progress) is
planned again.
"""

from __future__ import annotations

import collections
import dataclasses
import pickle

from .core.mission.share import PlanOutcome, PlanRequest, run_plan


class PlanMemo:
    """`run(request)`: `run_plan(request)`, planned once per distinct request."""

    def __init__(self, size: int = 8) -> None:
        self.size = size
        self._done: collections.OrderedDict[bytes, bytes] = collections.OrderedDict()
        self.planned = 0  # requests actually planned
        self.reused = 0  # requests answered from an earlier identical one

    def run(self, request: PlanRequest) -> PlanOutcome:
        canonical = dataclasses.replace(
            request,
            job_id=0,
            members=tuple(sorted(request.members, key=lambda m: m.profile.vehicle_id)),
            progress_m=dict(sorted(request.progress_m.items())),
        )
        key = pickle.dumps(canonical)
        got = self._done.get(key)
        if got is None:
            got = pickle.dumps(run_plan(request))
            self.planned += 1
            self._done[key] = got
            while len(self._done) > self.size:
                self._done.popitem(last=False)
        else:
            self.reused += 1
        outcome: PlanOutcome = pickle.loads(got)
        return dataclasses.replace(outcome, job_id=request.job_id)
