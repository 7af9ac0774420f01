"""`gcs target report`, `gcs vote`, and the vote shown by `mission --count`: bad input is
a one-line error and exit 2 with nothing sent; the vote table from votes as the
vehicles send them (the end-to-end run is tests/swarm_node/test_voting_processes.py)."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from gcs_cli.app import app
from gcs_cli.tasking import result_of, vote_table
from swarm_proto import Vote, VoteScore

runner = CliRunner()
NOWHERE = ["--connect", "tcp/127.0.0.1:1"]  # nothing listens: must fail before connecting


@pytest.mark.parametrize(
    "args",
    [
        ["target", "report", "--point", "95,0"],
        ["target", "report", "--point", "nan,0"],
        ["target", "report", "--point", "37.4,-5.9", "--confidence", "1.5"],
        ["target", "report", "--point", "37.4,-5.9", "--confidence", "nan"],
        ["target", "report", "--point", "37.4,-5.9", "--timeout", "-1"],
        ["target", "report", "--point", "37.4,-5.9", "--target-id", "-3"],
        ["target", "report", "--point", "37.4,-5.9", "--as-vehicle", "70000"],
        ["vote", "12", "--wait", "nan"],
        ["vote", "12", "--count", "0"],
        ["mission", "target", "--point", "37.4,-5.9", "--count", "2", "--vote-wait", "-1"],
    ],
)
def test_bad_input_is_refused_before_anything_is_sent(args: list[str]) -> None:
    r = runner.invoke(app, [*NOWHERE, *args])
    assert r.exit_code == 2, r.output
    assert "Traceback" not in r.output


def votes(committed: bool = True) -> dict[int, Vote]:
    table = (VoteScore(1, 0.71), VoteScore(7, 0.96), VoteScore(8, 0.96), VoteScore(9, 0.55))
    return {v: Vote(77, v, table, members_hash=0x1234, committed=committed) for v in (1, 7, 8, 9)}


def test_the_vote_table_ranks_as_the_vehicles_do() -> None:
    r = result_of(77, votes(), 2, went={7, 8})
    assert r.decided and r.winners == (7, 8)  # a tie at 0.96 goes to the lower id
    text = "\n".join(
        str(row)
        for row in vote_table(r).columns[2]._cells  # the decision column
    )
    assert text.count("goes") == 2 and text.count("stays") == 2
    undecided = result_of(77, votes(committed=False), None, went=set())
    assert not undecided.decided and undecided.winners is None
    assert set(undecided.scores) == {1, 7, 8, 9}


@pytest.mark.network
def test_a_vote_over_before_gcs_vote_listened_is_read_from_the_vehicles(
    zenoh_router: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """`gcs vote ID` said "no vote heard" 5-15 s after a vote while the winners flew:
    the winners are read from what they publish (VehicleInfo.mission_id)."""
    from gcs_cli.app import run
    from tests.gcs_cli.fake_vehicle import Vehicle

    vs = [Vehicle(zenoh_router, "vote", v, [], mission_id=77 if v != 9 else 0) for v in (7, 8, 9)]
    try:
        code = run(["--connect", zenoh_router, "--swarm", "vote", "vote", "77", "--wait", "1.5"])
        out = " ".join(capsys.readouterr().out.split())
        assert code == 0 and "mission 77: decided before this listened" in out, out
        assert "flown by 7, 8 (their VehicleInfo)" in out, out
        code = run(["--connect", zenoh_router, "--swarm", "vote", "vote", "78", "--wait", "1.5"])
        out = " ".join(capsys.readouterr().out.split())
        assert code == 1 and "mission 78: no vote heard and no vehicle flies it" in out, out
    finally:
        for v in vs:
            v.close()
