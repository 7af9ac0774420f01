"""Texts on the wire: an Ack's or an Alert's `text` holds 64 characters (ShortText, in
both encodings). The reason code carries the meaning (the ground station renders it
in full from its own table, gcs_cli/core/reasons.py); the text carries what is
particular to this vehicle and this time, written to fit. `short_text` fits a longer
one visibly: cut at a word boundary where it can be, ending in an ellipsis, so a
reader never takes a cut text for a whole one."""

from __future__ import annotations

TEXT_LIMIT = 64
ELLIPSIS = "…"


def short_text(text: str, limit: int = TEXT_LIMIT) -> str:
    """`text` unchanged when it fits `limit` characters, else cut to fit with "…"."""
    text = " ".join(text.split())  # one line
    if len(text) <= limit:
        return text
    cut = text[: limit - 1]
    space = cut.rfind(" ")
    if space >= limit // 2:  # keep whole words when that loses little
        cut = cut[:space]
    return cut.rstrip(" ,;:") + ELLIPSIS
