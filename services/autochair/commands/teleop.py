"""`autochair teleop` (being written)."""

from __future__ import annotations

from typing import Any


def register(sub: Any) -> None:
    sub.add_parser("teleop", help="(not yet available)").set_defaults(func=lambda _a: 2)
