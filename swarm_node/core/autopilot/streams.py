"""Asks the autopilot for the telemetry the tracker needs, and keeps asking.

When the link comes up (first HEARTBEAT, restored, autopilot rebooted) it sends one
SET_MESSAGE_INTERVAL (MAV_CMD 511) per message. If the autopilot answers any of them
UNSUPPORTED/DENIED, or not at all within `ack_timeout_s`, it falls back to the older
REQUEST_DATA_STREAM groups. A watchdog then re-requests any message that stopped
arriving (e.g. another GCS on the same link changed the rates).

Passthrough sessions (core/passthrough.py) may wish for more (`want`): each message is
asked at the faster of the node's rate and the wish, and a wish withdrawn goes back to
the node's rate (or to the autopilot's default, interval 0, for a message the node does
not use). A wish is sent only while no request of the node's own awaits its answers: a
COMMAND_ACK does not say which message it answers, and a refusal of a client's wish
must not switch the node's own streams to the fallback. With the fallback in use the
sessions get what the node streams.
"""

from __future__ import annotations

from collections.abc import Mapping

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .framing import MAVLinkMessage
from .mission_item import MavCmd

DEFAULT_RATES_HZ: Mapping[str, float] = {
    "GLOBAL_POSITION_INT": 10.0,
    "ATTITUDE": 10.0,
    "VFR_HUD": 4.0,
    "SYS_STATUS": 2.0,
    "BATTERY_STATUS": 1.0,
    "GPS_RAW_INT": 2.0,
    "SYSTEM_TIME": 2.0,
    "MISSION_CURRENT": 2.0,
    "EKF_STATUS_REPORT": 2.0,
    "HOME_POSITION": 0.5,
    "EXTENDED_SYS_STATE": 1.0,
}

# REQUEST_DATA_STREAM groups (MAV_DATA_STREAM) covering the messages above in ArduPilot
FALLBACK_STREAMS_HZ: Mapping[int, int] = {
    6: 10,  # POSITION: GLOBAL_POSITION_INT
    10: 10,  # EXTRA1: ATTITUDE
    11: 4,  # EXTRA2: VFR_HUD
    2: 2,  # EXTENDED_STATUS: SYS_STATUS, GPS_RAW_INT, MISSION_CURRENT
    12: 2,  # EXTRA3: SYSTEM_TIME, BATTERY_STATUS, EKF_STATUS_REPORT
}

#: Sent by ArduPilot without being asked often enough to re-request (or only on change).
NOT_WATCHED = frozenset({"HOME_POSITION", "EXTENDED_SYS_STATE", "BATTERY_STATUS"})


def _known(name: str) -> bool:
    return getattr(mavlink, f"MAVLINK_MSG_ID_{name}", None) is not None


def message_id(name: str) -> int:
    msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}", None)
    if msg_id is None:
        raise ValueError(f"unknown MAVLink message {name!r}")
    return int(msg_id)


class StreamRequester:
    def __init__(
        self,
        rates_hz: Mapping[str, float] = DEFAULT_RATES_HZ,
        *,
        ack_timeout_s: float = 2.0,
        watchdog_period_s: float = 5.0,
    ) -> None:
        self.rates_hz = dict(rates_hz)
        for name, rate in self.rates_hz.items():
            message_id(name)
            if not rate > 0:
                raise ValueError(f"rate of {name} must be positive")
        self.ack_timeout_s = ack_timeout_s
        self.watchdog_period_s = watchdog_period_s
        self.target: tuple[int, int] = (0, 0)
        self.use_fallback = False
        self.requests_sent = 0
        self._awaiting_acks = 0
        self._ack_deadline: float | None = None
        self._watch_at: float | None = None
        self._last_full_request = -1e18
        self._seen: dict[str, float] = {}
        self._requested_at: dict[str, float] = {}
        self.wishes: dict[str, float] = {}  # passthrough sessions' rates (`want`)
        self._wish_due: set[str] = set()  # wishes not sent yet

    def _interval(self, name: str, rate_hz: float | None = None) -> MAVLinkMessage:
        """SET_MESSAGE_INTERVAL for `name` at `rate_hz` (default: the node's; 0: the
        autopilot's own default)."""
        rate = self.rates_hz[name] if rate_hz is None else rate_hz
        interval_us = round(1e6 / rate) if rate > 0 else 0
        return mavlink.MAVLink_command_long_message(
            self.target[0],
            self.target[1],
            MavCmd.SET_MESSAGE_INTERVAL,
            0,
            float(message_id(name)),
            float(interval_us),
            0,
            0,
            0,
            0,
            0,
        )

    def want(self, wishes: Mapping[str, float], now: float) -> list[MAVLinkMessage]:
        """The sessions' wishes (message name -> Hz; names the dialect does not know
        are ignored): what changed is asked for now, or once the node's own requests
        are answered."""
        new = {n: hz for n, hz in wishes.items() if hz > 0 and _known(n)}
        self._wish_due |= {
            n for n in set(new) | set(self.wishes) if new.get(n) != self.wishes.get(n)
        }
        self.wishes = new
        return self._send_wishes()

    def _send_wishes(self) -> list[MAVLinkMessage]:
        if not self._wish_due or self.target == (0, 0) or self._awaiting_acks > 0:
            return []
        due, self._wish_due = sorted(self._wish_due), set()
        if self.use_fallback:
            return []
        out = []
        for n in due:
            own = self.rates_hz.get(n)
            wish = self.wishes.get(n, 0.0)
            out.append(self._interval(n, max(own or 0.0, wish)))
        self.requests_sent += len(out)
        return out

    def _fallback(self) -> list[MAVLinkMessage]:
        return [
            mavlink.MAVLink_request_data_stream_message(self.target[0], self.target[1], sid, hz, 1)
            for sid, hz in FALLBACK_STREAMS_HZ.items()
        ]

    def _request(self, names: list[str], now: float) -> list[MAVLinkMessage]:
        for name in names:
            self._requested_at[name] = now
        if self.use_fallback:
            out = self._fallback()
        else:
            out = [self._interval(n) for n in names]
            self._awaiting_acks += len(out)
            self._ack_deadline = now + self.ack_timeout_s
        self.requests_sent += len(out)
        return out

    def on_link_up(
        self, target: tuple[int, int], now: float, force: bool = True
    ) -> list[MAVLinkMessage]:
        """Request everything (`force` False: unless that was done in the last
        `watchdog_period_s`, so a flapping link does not flood the autopilot)."""
        self.target = target
        self._watch_at = now + self.watchdog_period_s
        if not force and now - self._last_full_request < self.watchdog_period_s:
            return []
        self._last_full_request = now
        self._awaiting_acks = 0
        self._wish_due |= set(self.wishes)  # asked again once these are answered
        return self._request(list(self.rates_hz), now)

    def note(self, mtype: str, now: float) -> None:
        if mtype in self.rates_hz:
            self._seen[mtype] = now

    def handle_ack(self, msg: MAVLinkMessage, now: float) -> list[MAVLinkMessage]:
        if int(msg.command) != MavCmd.SET_MESSAGE_INTERVAL or self._awaiting_acks <= 0:
            return []
        self._awaiting_acks -= 1
        if self._awaiting_acks == 0:
            self._ack_deadline = None
        if int(msg.result) in (2, 3) and not self.use_fallback:  # DENIED, UNSUPPORTED
            return self._switch_to_fallback(now)
        return self._send_wishes()  # (only once every one is answered)

    def _switch_to_fallback(self, now: float) -> list[MAVLinkMessage]:
        self.use_fallback = True
        self._awaiting_acks = 0
        self._ack_deadline = None
        return self._request(list(self.rates_hz), now)

    def next_deadline(self) -> float | None:
        a, b = self._ack_deadline, self._watch_at
        if a is None:
            return b
        return a if b is None or a < b else b

    def on_timer(self, now: float, link_ok: bool = True) -> list[MAVLinkMessage]:
        """`link_ok` False: only the fallback decision runs (the watchdog waits)."""
        out: list[MAVLinkMessage] = []
        if self._ack_deadline is not None and now >= self._ack_deadline:
            self._ack_deadline = None
            nothing_seen = not any(
                self._seen.get(n, -1.0) >= self._requested_at.get(n, 0.0) for n in self.rates_hz
            )
            if self._awaiting_acks > 0 and nothing_seen and not self.use_fallback:
                out += self._switch_to_fallback(now)
            self._awaiting_acks = 0
            if link_ok:
                out += self._send_wishes()
        if self._watch_at is not None and now >= self._watch_at:
            self._watch_at = now + self.watchdog_period_s
            if not link_ok:
                return out
            stale = [
                name
                for name, rate in self.rates_hz.items()
                if name not in NOT_WATCHED
                and now - max(self._seen.get(name, -1e18), self._requested_at.get(name, -1e18))
                > max(self.watchdog_period_s, 3.0 / rate)
            ]
            if stale:
                out += self._request(stale, now)
        return out
