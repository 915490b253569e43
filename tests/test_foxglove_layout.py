"""The shipped Foxglove layout (docs/foxglove-layout.json) names only channels a recording or
the live bridge has: a key of the table (and, for plots, a field of its message) or a derived
Foxglove topic. A renamed key or field would otherwise leave a panel silently empty."""

from __future__ import annotations

import json
from pathlib import Path

import msgspec

from autochair.logger import foxglove
from autochair_msgs import keys

LAYOUT = Path(__file__).resolve().parents[1] / "docs" / "foxglove-layout.json"


def test_every_topic_and_plotted_field_of_the_layout_exists() -> None:
    panels = json.loads(LAYOUT.read_text())["configById"]
    by_key = {t.key: t for t in keys.TOPICS if t.kind == "pub"}
    named: list[str] = []
    fields: list[tuple[str, str]] = []
    for cfg in panels.values():
        named += list(cfg.get("topics", {}))
        named += [cfg[k] for k in ("topicPath", "topicToRender") if k in cfg]
        for path in cfg.get("paths", []):
            topic, _, field = path["value"].partition(".")
            fields.append((topic, field))
    assert named and fields  # positive control: the parser found the panels' channels
    unknown = [t for t in named + [t for t, _ in fields]
               if t not in by_key and t not in foxglove.DERIVED]
    assert not unknown, f"layout names channels nothing publishes: {unknown}"
    missing = [f"{t}.{f}" for t, f in fields
               if f not in {x.name for x in msgspec.structs.fields(by_key[t].type)}]
    assert not missing, f"layout plots fields the messages lack: {missing}"
