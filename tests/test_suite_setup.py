"""How `make test` runs the suite: what the Makefile and the test setup rely on."""

from __future__ import annotations

import pytest


@pytest.mark.xdist_group("suite-setup")
def test_an_xdist_group_keeps_its_tests_on_one_worker(request: pytest.FixtureRequest) -> None:
    """`--dist loadgroup` (make test) sends a group's tests to one worker by adding the
    group's name to their node ids; when that suffix is missing, groups are ignored and a
    module-wide fixture (the demo story, the map's browser) is built on every worker."""
    if not getattr(request.config.option, "loadgroup", False):
        pytest.skip("not run with --dist loadgroup")
    assert request.node.nodeid.endswith("@suite-setup"), request.node.nodeid
