"""Fixtures: a free hub endpoint and a private stack that is always stopped."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from autochair.launcher import Launcher, free_port
from tests.helpers import make_stack


@pytest.fixture
def hub() -> str:
    return f"tcp/127.0.0.1:{free_port()}"


@pytest.fixture
def stack_factory(tmp_path: Path, hub: str) -> Iterator[Callable[..., Launcher]]:
    """Start a private stack (subset of the process list) on a free hub port; always stopped."""
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
