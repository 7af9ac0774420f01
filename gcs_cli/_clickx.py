"""The command-line library's exception classes, wherever the installed typer takes
them from (click itself in older typer, a vendored copy in newer): the ones its
`typer.BadParameter` comes with."""

from __future__ import annotations

import importlib
from typing import Any

import typer

_mod: Any = importlib.import_module(typer.BadParameter.__module__)
UsageError: type[Exception] = _mod.UsageError
ClickException: type[Exception] = _mod.ClickException
EXIT: type[BaseException] = getattr(_mod, "Exit", typer.Exit)
