"""Where the swarm database file lives: `--db PATH`, else `$BANDADA_DB`, else the
per-user data directory (`$XDG_DATA_HOME/bandada/swarm.db`, by default
`~/.local/share/bandada/swarm.db`)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

ENV_VAR = "BANDADA_DB"
FILE_NAME = "swarm.db"


def default_db_path(env: Mapping[str, str] | None = None) -> Path:
    env = os.environ if env is None else env
    data = env.get("XDG_DATA_HOME") or ""
    base = Path(data) if data and Path(data).is_absolute() else Path.home() / ".local" / "share"
    return base / "bandada" / FILE_NAME


def resolve_db_path(
    explicit: str | os.PathLike[str] | None = None, env: Mapping[str, str] | None = None
) -> Path:
    """The database path a process uses: the explicit one, `$BANDADA_DB`, or the default."""
    env = os.environ if env is None else env
    if explicit:
        return Path(explicit).expanduser()
    if env.get(ENV_VAR):
        return Path(env[ENV_VAR]).expanduser()
    return default_db_path(env)
