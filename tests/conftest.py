"""Fixtures: a free hub endpoint and a private stack that is always stopped."""

from __future__ import annotations

import os
from collections.abc import Callable, Generator, Iterator
from pathlib import Path

import pytest

from autochair.launcher import Launcher, free_port
from tests.helpers import make_stack


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook reads the groups
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Under xdist (`./dev test`: -n 2 --dist loadgroup) the system tests run one at a time in
    one worker, as they did serially: each is a whole stack on real time and deadlines, and two
    at once on a 2-core machine make the simulator fall behind real time. The other tests (in
    process, their own clocks) share the machine with them from the other worker."""
    for item in items:
        if item.get_closest_marker("slow") and not item.get_closest_marker("offline"):
            item.add_marker(pytest.mark.xdist_group("system"))


def pytest_runtest_setup(item: pytest.Item) -> None:
    """An xdist worker running the in-process tests yields the CPU to the system tests' stacks
    (which run on real-time deadlines): nice 10 from its first such test on. The worker with
    the system tests runs them all before any other test, so they keep their priority."""
    if os.environ.get("PYTEST_XDIST_WORKER") and not item.get_closest_marker("xdist_group") \
            and os.nice(0) == 0:
        os.nice(10)


def pytest_collection_finish(session: pytest.Session) -> None:
    """Fail loudly if xdist lost the groups (it marks them in the node ids, which pytest 9.2
    no longer lets it do: pytest-xdist#1386) rather than run two stacks at once."""
    if getattr(session.config.option, "loadgroup", False) and any(
            item.get_closest_marker("xdist_group") and "@" not in item.nodeid
            for item in session.items):
        raise pytest.UsageError("xdist's --dist loadgroup lost the test groups (pytest-xdist"
                                "#1386 with pytest 9.2): the system tests would run two at once")


@pytest.fixture
def hub() -> str:
    return f"tcp/127.0.0.1:{free_port()}"


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item
                               ) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    """Each phase's report on the test (`item.rep_call`), for fixtures that explain a failure."""
    report = yield
    setattr(item, f"rep_{report.when}", report)
    return report


def print_warnings(run_dir: Path, last: int = 12) -> None:
    """Each service's last warnings and errors (its log in `run_dir`): shown with a failed
    system test, so a rare failure (a safety stop nobody expected) names its cause."""
    for log in sorted(run_dir.glob("*.log")):
        lines = [ln for ln in log.read_text(errors="replace").splitlines()
                 if " WARNING " in ln or " ERROR " in ln or "Traceback" in ln]
        for ln in lines[-last:]:
            print(f"[{log.stem}] {ln}")


@pytest.fixture
def stack_factory(request: pytest.FixtureRequest, tmp_path: Path, hub: str
                  ) -> Iterator[Callable[..., Launcher]]:
    """Start a private stack (subset of the process list) on a free hub port; always stopped
    (and on a failure, each service's last warnings printed)."""
    launchers: list[Launcher] = []

    def start(names: list[str], restart: bool = False, **values: str) -> Launcher:
        launcher = make_stack(["router", *names], hub, tmp_path / "run", restart, **values)
        launchers.append(launcher)
        launcher.start(ready_timeout_s=30)
        return launcher

    try:
        yield start
    finally:
        for launcher in launchers:
            launcher.stop()
        report = getattr(request.node, "rep_call", None)
        if launchers and (report is None or report.failed):
            print_warnings(tmp_path / "run")
