"""`autochair deploy`: write deploy/ from the process list, or check it has not drifted."""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from autochair.cli import CliError


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "deploy", help="generate or check deploy/ (compose, supervisord, systemd, zenoh)",
        description="deploy/ is generated from autochair/processes.py; never edit it by hand.")
    act = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    g = act.add_parser("generate", help="write the deploy files")
    g.add_argument("--out", default="deploy", help="output directory (default: deploy)")
    c = act.add_parser("check", help="fail if the files differ from what the list generates")
    c.add_argument("--dir", default="deploy", help="directory to check (default: deploy)")
    i = act.add_parser(
        "image", help="build the stack's Docker image (wheels made here, installed offline)",
        description="Build the image of deploy/Dockerfile: the project's wheels are built on "
                    "this machine and installed in the image with --no-index (the build itself "
                    "uses no network). --offline: no image registry either; the Debian "
                    "bookworm base is bootstrapped here with debootstrap (once).")
    i.add_argument("--offline", action="store_true",
                   help="base on a Debian bookworm made here by debootstrap (as root; kept as "
                        "autochair-base:bookworm) instead of pulling python:3.11-slim-bookworm")
    i.add_argument("--base", help="base image to use as it is (a Debian bookworm with python3)")
    i.add_argument("--rebootstrap", action="store_true",
                   help="with --offline: bootstrap the base again even if it exists")
    i.add_argument("--mirror", help="Debian mirror for debootstrap (default: this machine's "
                   "apt source, else http://deb.debian.org/debian)")
    i.add_argument("--tag", default="autochair:latest", help="image tag (default %(default)s)")
    i.add_argument("--work-dir", default=os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "autochair", "image"),
        help="wheelhouse and build context (default %(default)s)")
    i.add_argument("--source", help="the autochair checkout to build (default: the one this "
                   "command runs from, else the current directory)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autochair import deploy

    if args.action == "image":
        return build_image(args)
    try:
        if args.action == "generate":
            for path in deploy.write(Path(args.out)):
                print(path)
            return 0
        bad = deploy.drift(Path(args.dir))
    except deploy.DeployError as e:
        raise CliError(str(e)) from None
    if bad:
        raise CliError(f"{args.dir} drifted from the process list: {', '.join(bad)} "
                       "(run `autochair deploy generate`)")
    print(f"{args.dir}: up to date")
    return 0


# --- `autochair deploy image` ---------------------------------------------------------------------
# Steps: [base] debootstrap + docker import (--offline, once) · [wheels] pip wheel with this
# machine's index or cache · [build] docker build --network none from the wheelhouse.
DEFAULT_MIRROR = "http://deb.debian.org/debian"
SOURCE_DATE_EPOCH = "315532800"  # 1980-01-01: the same source makes the same wheel (cached layer)
# Not needed in a container: docs, man pages, translations, apt's downloaded lists and packages.
SLIM = ("usr/share/doc", "usr/share/man", "usr/share/info", "usr/share/locale",
        "var/cache/apt", "var/lib/apt/lists", "var/log")


def _say(msg: str) -> None:
    print(msg, flush=True)


def _run_progress(cmd: list[str], what: str, show: Callable[[str], str | None],
                  env: dict[str, str] | None = None, tail: int = 15) -> None:
    """Run `cmd`, printing what `show` makes of each output line (None: nothing); on failure a
    one-line error (after the last `tail` lines of its output)."""
    import subprocess
    from collections import deque

    last: deque[str] = deque(maxlen=tail)
    try:
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                env=env, errors="replace")
    except OSError as e:
        raise CliError(f"{what}: cannot run {cmd[0]}: {e.strerror}") from None
    assert proc.stdout is not None
    for line in proc.stdout:
        line = line.rstrip()
        last.append(line)
        shown = show(line)
        if shown:
            _say(f"  {shown}")
    if proc.wait() != 0:
        for line in last:
            print(f"  | {line}", file=sys.stderr)
        raise CliError(f"{what} failed (exit {proc.returncode}; its last lines above)")


def _docker(*args: str) -> str:
    import subprocess

    r = subprocess.run(["docker", *args], capture_output=True, text=True)
    return r.stdout.strip() if r.returncode == 0 else ""


def _docker_ready() -> str:
    import subprocess

    if not shutil.which("docker"):
        raise CliError("docker not found: install Docker (Debian: apt-get install docker.io)")
    r = subprocess.run(["docker", "version", "--format", "{{.Server.Version}}"],
                       capture_output=True, text=True)
    if r.returncode != 0 or not r.stdout.strip():
        raise CliError("cannot reach the Docker daemon: start it (`systemctl start docker`, "
                       "or as root `dockerd &`) and check you may use it (root or group docker)")
    return r.stdout.strip()


def _apt_mirror() -> str:
    """This machine's Debian mirror (deb822 or one-line apt sources), else deb.debian.org."""
    import re

    files = [Path("/etc/apt/sources.list"),
             *sorted(Path("/etc/apt/sources.list.d").glob("*.sources")),
             *sorted(Path("/etc/apt/sources.list.d").glob("*.list"))]
    for f in files:
        try:
            text = f.read_text()
        except OSError:
            continue
        for m in re.finditer(r"^(?:URIs:\s*|deb\s+(?:\[[^]]*\]\s+)?)(\S+)", text, re.M):
            uri = m.group(1)
            if uri.startswith("http") and uri.rstrip("/").endswith("/debian"):
                return uri
    return DEFAULT_MIRROR


def _mounts_under(root: Path) -> list[str]:
    try:
        lines = Path("/proc/self/mounts").read_text().splitlines()
    except OSError:
        return []
    points = [ln.split()[1].replace("\\040", " ") for ln in lines if len(ln.split()) > 1]
    return sorted((p for p in points if p == str(root) or p.startswith(f"{root}/")),
                  key=len, reverse=True)


def _remove_rootfs(root: Path) -> None:
    """Remove a (maybe half-made) debootstrap target: unmount what it mounted first."""
    import subprocess

    for point in _mounts_under(root):
        subprocess.run(["umount", "-l", point], capture_output=True)
    if _mounts_under(root):
        raise CliError(f"{root}: still has mounts; unmount them and remove it by hand")
    shutil.rmtree(root, ignore_errors=True)


def bootstrap_base(tag: str, work: Path, mirror: str) -> None:
    """debootstrap a minimal Debian bookworm with python3, slim it, `docker import` it."""
    import subprocess

    if not shutil.which("debootstrap"):
        raise CliError("debootstrap not found: apt-get install debootstrap (or give --base)")
    if os.geteuid() != 0:
        raise CliError("debootstrap needs root: run `autochair deploy image --offline` as root "
                       "(or give --base IMAGE)")
    root = work / f"rootfs-{os.getpid()}"
    _say(f"[base] debootstrap --variant=minbase --include=python3 bookworm from {mirror} "
         "(about a minute) ...")
    t0 = time.monotonic()
    seen: set[str] = set()

    def show(line: str) -> str | None:
        # "I: Retrieving X", "I: Validating X", ...: a line per phase, not one per package.
        if not line.startswith(("I: ", "E: ", "W: ")):
            return None
        word = line[3:].split(" ", 1)[0]
        if line.startswith("I: ") and word in seen:
            return None
        seen.add(word)
        return f"{time.monotonic() - t0:3.0f} s  {line[3:]}"

    try:
        _run_progress(["debootstrap", "--variant=minbase", "--include=python3", "bookworm",
                       str(root), mirror], "debootstrap", show)
        for rel in SLIM:
            path = root / rel
            if path.is_dir():
                for child in path.iterdir():
                    if child.is_dir() and not child.is_symlink():
                        shutil.rmtree(child)
                    else:
                        child.unlink()
        _say(f"[base] docker import as {tag} ...")
        tar = subprocess.Popen(["tar", "-C", str(root), "--numeric-owner", "--exclude=./proc/*",
                                "--exclude=./sys/*", "-c", "."], stdout=subprocess.PIPE)
        r = subprocess.run(["docker", "import", "--change", 'CMD ["python3"]', "-", tag],
                           stdin=tar.stdout, capture_output=True, text=True)
        assert tar.stdout is not None
        tar.stdout.close()
        if tar.wait() != 0 or r.returncode != 0:
            raise CliError(f"docker import of the base failed: {r.stderr.strip()[-300:]}")
    finally:
        _remove_rootfs(root)
    _say(f"[base] {tag} ready in {time.monotonic() - t0:.0f} s")


def _wheel_python() -> str:
    """A Python 3.11 (the image's) to build the wheels with: this one, else python3.11."""
    if sys.version_info[:2] == (3, 11):
        return sys.executable
    other = shutil.which("python3.11")
    if other is None:
        raise CliError("the image runs Python 3.11: building its wheels needs a python3.11 "
                       f"here (this is Python {sys.version_info[0]}.{sys.version_info[1]})")
    return other


def _pip_wheel_file(python: str, dest: Path) -> None:
    """pip itself, as a wheel: the bundled one of ensurepip, else downloaded."""
    import subprocess

    found = subprocess.run([python, "-c", "import ensurepip, pathlib; print(*sorted(pathlib.Path("
                            "ensurepip.__file__).parent.glob('_bundled/pip-*.whl')))"],
                           capture_output=True, text=True).stdout.split()
    if found:
        shutil.copyfile(found[-1], dest)
        return
    tmp = dest.parent / "pip-download"
    _run_progress([python, "-m", "pip", "download", "-q", "--no-deps", "-d", str(tmp), "pip"],
                  "pip download pip", lambda _l: None)
    shutil.copyfile(next(tmp.glob("pip-*.whl")), dest)
    shutil.rmtree(tmp)


def build_wheelhouse(source: Path, context: Path) -> None:
    """context/wheelhouse/deps: every dependency's wheel + pip.whl + requirements.txt;
    context/wheelhouse/app: autochair's own wheel (changes most often: its own layer)."""
    python = _wheel_python()
    src = context / "src"
    shutil.rmtree(src, ignore_errors=True)
    src.mkdir(parents=True)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(source / name, src / name)
    for name in ("schemas", "services"):
        shutil.copytree(source / name, src / name,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info"))
    out = context / "wheels-new"
    shutil.rmtree(out, ignore_errors=True)
    _say(f"[wheels] pip wheel (Python {python}) ...")
    t0 = time.monotonic()
    env = {**os.environ, "SOURCE_DATE_EPOCH": SOURCE_DATE_EPOCH}
    _run_progress([python, "-m", "pip", "wheel", "--progress-bar", "off", "-w", str(out),
                   str(src)], "pip wheel",
                  lambda line: f"saved {Path(line.split()[-1]).name}" if line.startswith(
                      "Saved ") else None, env=env)
    shutil.rmtree(src)
    house = context / "wheelhouse"
    shutil.rmtree(house, ignore_errors=True)
    (house / "deps").mkdir(parents=True)
    (house / "app").mkdir()
    deps = []
    for whl in sorted(out.glob("*.whl")):
        if whl.name.startswith("autochair-"):
            whl.rename(house / "app" / whl.name)
        else:
            whl.rename(house / "deps" / whl.name)
            deps.append(f"./{whl.name}")
    shutil.rmtree(out)
    if not list((house / "app").glob("*.whl")):
        raise CliError(f"pip wheel made no autochair wheel from {source}")
    (house / "deps" / "requirements.txt").write_text("\n".join(deps) + "\n")
    _pip_wheel_file(python, house / "deps" / "pip.whl")
    size = sum(f.stat().st_size for f in house.rglob("*") if f.is_file())
    _say(f"[wheels] {len(deps) + 1} wheels, {size / 1e6:.0f} MB, in {time.monotonic() - t0:.0f} s")


def _source_dir(arg: str | None) -> Path:
    import autochair

    candidates = [Path(arg)] if arg else [Path(autochair.__file__).resolve().parents[2],
                                          Path.cwd()]
    for c in candidates:
        if (c / "pyproject.toml").is_file() and (c / "services" / "autochair").is_dir():
            return c.resolve()
    raise CliError(f"no autochair checkout at {candidates[0]} (give --source DIR)")


def build_image(args: argparse.Namespace) -> int:
    from autochair import deploy

    t_all = time.monotonic()
    source = _source_dir(args.source)
    server = _docker_ready()
    if args.base and args.offline:
        raise CliError("give --offline or --base, not both")
    base = args.base or (deploy.LOCAL_BASE if args.offline else deploy.PUBLIC_BASE)
    work = Path(args.work_dir)
    context = work / "context"
    try:
        context.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise CliError(f"cannot create {context}: {e.strerror}") from None
    _say(f"autochair deploy image: {args.tag} from {base} (Docker {server}; work dir {work})")
    if args.offline and (args.rebootstrap or not _docker("image", "inspect", base)):
        bootstrap_base(base, work, args.mirror or _apt_mirror())
    build_wheelhouse(source, context)
    dockerfile = context / "Dockerfile"
    committed = source / "deploy" / "Dockerfile"
    dockerfile.write_text(committed.read_text() if committed.is_file() else deploy.DOCKERFILE)
    _say(f"[build] docker build --network none -t {args.tag} --build-arg BASE={base} ...")
    t0 = time.monotonic()
    # The classic builder: in every Docker CLI with any daemon, and no plugin needed.
    env = {**os.environ, "DOCKER_BUILDKIT": "0"}
    _run_progress(["docker", "build", "--network", "none", "--pull=false", "-t", args.tag,
                   "--build-arg", f"BASE={base}", "-f", str(dockerfile), str(context)],
                  "docker build",
                  lambda line: line if line.startswith(("Step ", " ---> Using cache"))
                  else None, env=env)
    size = int(_docker("image", "inspect", "--format", "{{.Size}}", args.tag) or 0)
    _say(f"[build] done in {time.monotonic() - t0:.0f} s")
    _say(f"{args.tag}: {size / 1e6:.0f} MB (base {base}); ready in "
         f"{time.monotonic() - t_all:.0f} s. Next: cd deploy && docker-compose --profile chair "
         "up -d (or --profile sim)")
    return 0
