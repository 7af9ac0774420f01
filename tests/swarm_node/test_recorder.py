"""The node's flight recorder on real Zenoh (127.0.0.1): every VehicleStatus heard, its
own publications included, lands in the trajectory CSV that `gcs analyze` reads."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from swarm_node.cli import app as node_app
from swarm_node.runtime.recorder import StatusRecorder
from swarm_proto import VehicleStatus
from swarm_proto.session import SwarmBus, ZenohSettings
from swarm_proto.trajectory import HEADER, read_trajectory

pytestmark = pytest.mark.network


def status(vid: int, t: float) -> VehicleStatus:
    return VehicleStatus(
        vehicle_id=vid,
        time_unix_s=t,
        lat_deg=40.0 + vid * 1e-4,
        lon_deg=-3.0,
        alt_msl_m=700.0 + vid,
        alt_rel_m=50.0,
        vel_north_m_s=1.5,
    )


def test_statuses_heard_and_published_are_recorded(zenoh_router: str, tmp_path: Path) -> None:
    path = tmp_path / "rec.csv"
    rec = StatusRecorder(path)
    own = SwarmBus.open(ZenohSettings(connect=(zenoh_router,)))
    peer = SwarmBus.open(ZenohSettings(connect=(zenoh_router,)))
    try:
        rec.attach(own)
        heard: set[int] = set()
        t = 1.75e9
        for _ in range(100):  # discovery takes a moment: publish until both are recorded
            t += 0.2
            own.publish(status(1, t))
            peer.publish(status(2, t))
            rec.writer.flush()
            heard = (
                set(read_trajectory(path).vehicle.tolist())
                if path.read_text().count("\n") > 1
                else set()
            )
            if heard == {1, 2}:
                break
            time.sleep(0.05)  # waiting for delivery, not measuring it
        assert heard == {1, 2}
    finally:
        own.close()
        peer.close()
        rec.close()
    lines = path.read_text().splitlines()
    assert lines[0] == HEADER + ",alt_rel_m,vel_north_m_s,vel_east_m_s,vel_down_m_s"
    tr = read_trajectory(path)
    row = list(tr.vehicle).index(2)
    assert tr.lat[row] == pytest.approx(40.0002) and tr.alt_m[row] == 702.0
    rec.on_message(status(3, 0.0))  # after close: dropped, no error


def test_record_to_an_unwritable_path_is_a_one_line_error(tmp_path: Path) -> None:
    result = CliRunner().invoke(
        node_app, ["run", "--id", "1", "--record", str(tmp_path / "no" / "such" / "dir.csv")]
    )
    assert result.exit_code == 2
    assert "--record" in result.output and "Traceback" not in result.output


def test_a_predicted_status_is_not_recorded(tmp_path: Path) -> None:
    """A radio gateway's prediction of a peer is a belief, not a sample."""
    import msgspec

    path = tmp_path / "rec.csv"
    rec = StatusRecorder(path)
    rec.on_message(status(1, 1.75e9))
    rec.on_message(
        msgspec.structs.replace(status(2, 1.75e9), predicted_s=0.4, position_error_m=1.0)
    )
    rec.close()
    assert read_trajectory(path).vehicle.tolist() == [1]
