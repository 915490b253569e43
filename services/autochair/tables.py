"""The key table and the process list, rendered as Markdown for the README.

`python -m autochair.tables` rewrites the marked blocks of README.md; a test fails when they
drift from schemas/autochair_msgs/keys.py or services/autochair/processes.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

from autochair.processes import PROCESSES
from autochair_msgs import keys


def keys_table() -> str:
    rows = ["| key | type | rate | logged | what |", "|---|---|---|---|---|"]
    for t in keys.TOPICS:
        rate = "event" if t.rate_hz is None else f"{t.rate_hz:g} Hz"
        kind = t.type.__name__ + (f" → {t.reply.__name__}" if t.reply else "")
        if t.kind == "query":
            rate = "query"
        rows.append(f"| `{t.key}` | {kind} | {rate} | {'yes' if t.logged else 'no'} "
                    f"| {t.doc} |")
    rows.append(f"| `{keys.ALIVE}` | liveliness token | — | no | one per running service |")
    rows.append(f"| `{keys.HUB_PROBE}` | query, empty reply | 4 Hz | no | the hub asks itself "
                "through a client link; its watchdog pings only while it answers |")
    return "\n".join(rows)


def processes_table() -> str:
    rows = ["| process | command | sim only | what |", "|---|---|---|---|"]
    for p in PROCESSES:
        cmd = " ".join([p.script, *p.args])
        rows.append(f"| {p.name} | `{cmd}` | {'yes' if p.sim_only else ''} | {p.doc} |")
    return "\n".join(rows)


BLOCKS = {"keys": keys_table, "processes": processes_table}


def render(text: str) -> str:
    """Replace the body of each `<!-- name:begin -->` … `<!-- name:end -->` block."""
    for name, make in BLOCKS.items():
        begin, end = f"<!-- {name}:begin -->\n", f"\n<!-- {name}:end -->"
        i = text.find(begin)
        j = text.find(end, i)
        if i >= 0 and j >= 0:
            text = text[: i + len(begin)] + make() + text[j:]
    return text


def main() -> int:
    readme = Path(__file__).resolve().parents[2] / "README.md"
    text = readme.read_text()
    new = render(text)
    if new != text:
        readme.write_text(new)
        print(f"updated {readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
