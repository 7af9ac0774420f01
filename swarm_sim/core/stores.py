"""The autopilot's item stores: the mission (AP_Mission, with where AUTO is in it), the
fence (AC_PolyFence_loader's storage) and the rally points (AP_Rally), each uploaded and
downloaded with its own `ItemTransfer` (the MAVLink mission protocol)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .mission import FENCE, MISSION, RALLY, ItemTransfer, MissionItem


def is_nav(command: int) -> bool:
    """A NAV command (it moves the vehicle); the others are DO commands."""
    return command <= 95 or command in (213, 42702, 42703)


@dataclass
class MissionProgress:
    """Where AUTO is in the mission."""

    seq: int = 0  # current NAV command index, 0: none
    running: bool = False
    complete: bool = False
    jumps: dict[int, int] = field(default_factory=dict)  # DO_JUMP index -> times taken
    # AP_Mission's in_landing_sequence flag (ArduPlane): set when the mission lands or
    # jumps to DO_LAND_START, cleared when the current item is set; ArduPlane refuses to
    # arm while it is set ("Arm: In landing sequence"; seen against SITL)
    in_landing_sequence: bool = False

    def rewind(self) -> None:
        """Back to the start: no current item, no jump taken."""
        self.seq = 0
        self.complete = False
        self.jumps.clear()
        self.in_landing_sequence = False

    def current_fields(self, total: int, in_auto: bool) -> tuple[int, int, int, int]:
        """MISSION_CURRENT's seq, total, mission_state, mission_mode."""
        if total == 0:
            state = 1  # NO_MISSION
        elif self.complete:
            state = 5
        elif self.running and in_auto:
            state = 3
        else:
            state = 2
        seq = 0 if self.complete else self.seq
        return seq, total, state, 1 if in_auto else 0


class ItemStores:
    """Mission, fence and rally items and their transfers. `home_item` is mission item 0;
    `on_change(mission_type)` runs when an upload or a clear completes (its messages
    follow the MISSION_ACK)."""

    def __init__(
        self,
        *,
        home_item: Callable[[], MissionItem],
        on_change: Callable[[int], list[Any]],
        statustext: Callable[[int, str], Any],
    ) -> None:
        self.mission: list[MissionItem] = []
        self.fence: list[MissionItem] = []
        self.rally: list[MissionItem] = []
        self.progress = MissionProgress()
        self.transfers: dict[int, ItemTransfer] = {
            MISSION: ItemTransfer(
                MISSION,
                self.mission,
                home_item=home_item,
                current_seq=lambda: self.progress.seq,
                on_change=on_change,
                statustext=statustext,
            ),
            FENCE: ItemTransfer(FENCE, self.fence, on_change=on_change, statustext=statustext),
            RALLY: ItemTransfer(RALLY, self.rally, on_change=on_change, statustext=statustext),
        }
        self._each = tuple(self.transfers.values())

    @property
    def mission_total(self) -> int:
        """Mission items without home (MIS_TOTAL, MISSION_CURRENT.total)."""
        return max(0, len(self.mission) - 1)

    def starts_with_takeoff(self) -> bool:
        """The mission's first NAV command is a take-off."""
        for item in self.mission[1:]:
            if is_nav(item.command):
                return item.command in (22, 84)
        return False

    def update(self, now: float) -> list[Any]:
        """Protocol timeouts and resent requests of the uploads in progress."""
        out: list[Any] = []
        for transfer in self._each:
            if transfer.receiving:
                out.extend(transfer.update(now))
        return out

    def next_deadline(self) -> float | None:
        due: float | None = None
        for transfer in self._each:
            if transfer.receiving:
                d = transfer.next_deadline()
                if d is not None and (due is None or d < due):
                    due = d
        return due

    def keep(self, other: ItemStores) -> None:
        """Take `other`'s items (a reboot that keeps the stores)."""
        self.mission[:] = other.mission
        self.fence[:] = other.fence
        self.rally[:] = other.rally
