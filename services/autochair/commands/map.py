"""`autochair map save NAME`: the localization service writes its map as NAME.pgm + NAME.yaml
(ROS map_server format) into its maps directory; start it with `--map NAME` to localize on it.
`autochair map show FILE.yaml`: size, resolution and origin of a map file."""

from __future__ import annotations

import argparse
from typing import Any

from autochair.cli import CliError
from autochair.commands.link import add_link_args


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser("map", help="save or inspect maps",
                                                description=__doc__)
    verbs = p.add_subparsers(dest="verb", required=True, metavar="VERB")
    save = verbs.add_parser("save", help="save the current map as NAME (PGM + YAML)")
    save.add_argument("name", metavar="NAME")
    add_link_args(save)
    save.set_defaults(func=run_save)
    show = verbs.add_parser("show", help="describe a map file (NAME.yaml)")
    show.add_argument("path", metavar="FILE.yaml")
    show.set_defaults(func=run_show)


def run_save(args: argparse.Namespace) -> int:
    from autochair.commands.link import ask
    from autochair.mapping.mapfile import MapFileError, map_path
    from autochair_msgs import MapSaveReply, MapSaveRequest, keys

    try:
        map_path(".", args.name)  # refuse a bad name before asking the chair
    except MapFileError as e:
        raise CliError(str(e)) from None
    reply = ask(args, keys.MAP_SAVE, MapSaveRequest(name=args.name), MapSaveReply)
    print(f"map saved: {reply.path}", flush=True)
    return 0


def run_show(args: argparse.Namespace) -> int:
    from autochair.mapping.mapfile import MapFileError, load_map

    try:
        m = load_map(args.path)
    except MapFileError as e:
        raise CliError(str(e)) from None
    h, w = m.occupied.shape
    print(f"{args.path}: {w} × {h} cells of {m.resolution_m:g} m "
          f"({w * m.resolution_m:.1f} × {h * m.resolution_m:.1f} m), origin "
          f"({m.origin_x_m:.2f}, {m.origin_y_m:.2f}), {int(m.occupied.sum())} occupied, "
          f"{int(m.free.sum())} free")
    return 0
