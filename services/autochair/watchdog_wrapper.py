"""autochair-watchdog: run one service with the hung-process watchdog (for supervisord).

    autochair-watchdog [--timeout S] [--stop-grace S] -- CMD [ARGS...]

supervisord has no sd_notify watchdog, so deploy/supervisord.conf runs each service through
this wrapper. It gives CMD a $NOTIFY_SOCKET, forwards SIGTERM, SIGINT, SIGHUP, SIGQUIT, SIGUSR1
and SIGUSR2 to it, and once CMD has sent its first WATCHDOG=1, SIGKILLs it when the pings stop
for --timeout seconds or when it reports its own loops late (WATCHDOG=trigger); it then exits
with status 124 so that supervisord's autorestart starts it again. Otherwise it exits with
CMD's status (128 + N when CMD died of signal N). `supervisorctl pid` shows the wrapper: a
signal sent to it reaches CMD, and SIGKILLing it SIGKILLs CMD too (PR_SET_PDEATHSIG). The
bookkeeping is the launcher's (autochair.runtime.watchdog).
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import subprocess
import sys
import time

from autochair.launcher import _die_with_parent
from autochair.runtime.watchdog import NotifyChannel

HUNG_EXIT = 124  # as timeout(1): the command was stopped for taking too long
FORWARDED = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT, signal.SIGUSR1,
             signal.SIGUSR2)
STOPS = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP, signal.SIGQUIT)


def exit_status(returncode: int) -> int:
    return returncode if returncode >= 0 else 128 - returncode


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="autochair-watchdog", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--timeout", type=float, default=1.5,
                        help="kill CMD when its pings stop this long (s, default %(default)s)")
    parser.add_argument("--stop-grace", type=float, default=5.0,
                        help="after a stop signal, kill CMD if still running after this (s)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- CMD [ARGS...]")
    args = parser.parse_args(argv)
    cmd = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not cmd:
        parser.error("give the command to run after --")
    if not (args.timeout > 0 and args.stop_grace > 0):
        parser.error("--timeout and --stop-grace must be > 0")
    name = os.path.basename(cmd[0])
    channel = NotifyChannel.open(name, args.timeout, args.stop_grace)
    child: subprocess.Popen[bytes] | None = None
    early: list[int] = []  # signals that came before the child existed

    def forward(signum: int, _frame: object) -> None:
        if signum in STOPS:
            channel.watch.stopping(time.monotonic())  # a stop is not a hang
        if child is None:
            early.append(signum)
        else:
            child.send_signal(signum)

    for sig in FORWARDED:
        signal.signal(sig, forward)
    try:
        # SIGKILLing the wrapper kills the service the same way (as `kill -9` of the pid that
        # supervisorctl shows did before the wrapper), and never leaves it orphaned.
        child = subprocess.Popen(cmd, env={**os.environ, "NOTIFY_SOCKET": channel.address},
                                 preexec_fn=lambda: _die_with_parent(signal.SIGKILL))
    except OSError as e:
        print(f"autochair-watchdog: cannot run {cmd[0]}: {e}", file=sys.stderr, flush=True)
        return 127
    channel.expect(child.pid)
    for signum in early:
        child.send_signal(signum)
    try:
        while True:
            select.select([channel], [], [], 0.1)
            code = child.poll()
            if code is not None:
                return exit_status(code)
            reason = channel.poll(time.monotonic())
            if reason is not None:
                print(f"autochair-watchdog: {name} (pid {child.pid}) hung: {reason}; "
                      "killing it (SIGKILL)", file=sys.stderr, flush=True)
                child.kill()
                child.wait()
                return HUNG_EXIT
    finally:
        channel.close()


if __name__ == "__main__":
    sys.exit(main())
