"""The README shows the one key table and the one process list, exactly as the code has them."""

from __future__ import annotations

from pathlib import Path

from autochair import tables
from autochair.processes import PROCESSES
from autochair_msgs import keys

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_tables_are_current() -> None:
    text = README.read_text()
    for name in tables.BLOCKS:
        assert f"<!-- {name}:begin -->" in text, f"README lacks the {name} block"
    assert tables.render(text) == text, "README tables drifted: run python -m autochair.tables"


def test_every_key_is_unique_and_typed() -> None:
    seen = [t.key for t in keys.TOPICS]
    assert len(seen) == len(set(seen))
    for t in keys.TOPICS:
        assert t.key.startswith(keys.PREFIX + "/")
        assert (t.kind == "query") == (t.reply is not None)


def test_every_process_module_exists() -> None:
    import importlib.util

    for p in PROCESSES:
        assert importlib.util.find_spec(p.module) is not None, p.module
