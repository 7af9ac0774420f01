"""The messages a simulated autopilot sends, in the order it sends them. Every component
appends to the one `Outbox`; `SimAutopilot` hands them out after each input or timer."""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink


def statustext(severity: int, text: str) -> Any:
    """STATUSTEXT as ArduPilot sends it (at most 50 bytes)."""
    return mavlink.MAVLink_statustext_message(severity, text.encode()[:50], 0, 0)


class Outbox:
    def __init__(self) -> None:
        self._messages: list[Any] = []

    def send(self, msg: Any) -> None:
        self._messages.append(msg)

    def extend(self, messages: list[Any]) -> None:
        self._messages.extend(messages)

    def text(self, severity: int, text: str) -> None:
        self._messages.append(statustext(severity, text))

    def mark(self) -> int:
        """A place in the queue, for `insert_at` (a COMMAND_ACK goes before what the
        command caused)."""
        return len(self._messages)

    def insert_at(self, mark: int, msg: Any) -> None:
        self._messages.insert(mark, msg)

    def flush(self) -> list[Any]:
        out, self._messages = self._messages, []
        return out
