"""`gcs`: the ground station command line (paper section 3). This module only assembles
the commands, which live in their own modules (cli.py: status, commands, missions and
zones; monitor.py, recovery.py, plot.py, files.py, db.py, analyze.py, tasking.py,
declared.py), and runs them: `main` is the `gcs` entry point.

The commands appear in `gcs --help` in the order they are added here.
"""

from __future__ import annotations

import os
import sys

import typer

from . import _clickx, analyze, cli, db, declared, files, monitor, plot, recovery, tasking
from .common import link_options
from .map.command import map_command

app = typer.Typer(
    help="bandada ground station: fleet status, commands, missions, zones, files and plots.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)
app.callback()(link_options)  # --connect, --zenoh-config, --swarm, --gcs-id: ctx.obj, a Link
app.command("vote")(tasking.vote)
app.command(name="declared")(declared.declared)
# groups added without a name put their commands at the top level
app.add_typer(cli.app)  # status, alerts, peers, cmd, mission, version
app.add_typer(monitor.app)  # watch, vehicle, fleets
app.add_typer(recovery.app)  # save, load
app.add_typer(plot.app)  # plot, record
app.add_typer(db.app, name="db")
zone_app = typer.Typer(help="No-fly zones and operating areas.", no_args_is_help=True)
zone_app.add_typer(cli.zone_app)  # add, remove
zone_app.add_typer(files.zone_app)  # list, export, import
app.add_typer(zone_app, name="zone")
app.add_typer(analyze.app, name="analyze")
app.add_typer(tasking.app, name="target")  # re-tasking, and the vote shown
app.command("map")(map_command)  # the live map in a browser


def main(argv: list[str] | None = None) -> None:
    """The `gcs` entry point (exits with `run`'s code)."""
    sys.exit(run(argv))


def run(argv: list[str] | None = None) -> int:
    """`gcs` with these arguments, its exit code returned: a usage error or a bad value is one line on stderr and
    exit 2 (nothing sent); a failure the operator can act on (no router) one line and
    exit 1; anything else one line and exit 1 (GCS_DEBUG=1 shows the traceback)."""
    try:
        rv = app(args=argv, prog_name="gcs", standalone_mode=False)
    except _clickx.UsageError as exc:
        ctx = getattr(exc, "ctx", None)
        where = ctx.command_path if ctx is not None else "gcs"
        print(f"{where}: {' '.join(exc.format_message().split())}", file=sys.stderr)  # type: ignore[attr-defined]
        return 2
    except _clickx.ClickException as exc:
        print(f"gcs: {' '.join(exc.format_message().split())}", file=sys.stderr)  # type: ignore[attr-defined]
        return int(getattr(exc, "exit_code", 1))
    except SystemExit as exc:  # --show-completion and friends exit on their own
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except (typer.Abort, KeyboardInterrupt, BrokenPipeError):
        print("gcs: aborted", file=sys.stderr)
        return 130
    except Exception as exc:
        if os.environ.get("GCS_DEBUG"):
            raise
        text = " ".join(str(exc).split()) or type(exc).__name__
        print(f"gcs: error: {text} (GCS_DEBUG=1 shows where)", file=sys.stderr)
        return 1
    return rv if isinstance(rv, int) else 0


if __name__ == "__main__":
    main()
