"""Every command of a Typer app, as argument paths (["zone", "add"], ...)."""

from __future__ import annotations

import typer
from typer.main import get_command


def commands(app: typer.Typer) -> list[list[str]]:
    root = get_command(app)
    out: list[list[str]] = []

    def walk(cmd: object, path: list[str]) -> None:
        subs = getattr(cmd, "commands", None)
        if subs:
            for name, sub in sorted(subs.items()):
                walk(sub, [*path, name])
        else:
            out.append(path)

    walk(root, [])
    return out
