"""``python -m hoap_actions`` and the ``hoap-actions`` command: the command line of :mod:`hoap_actions.apps.cli`."""

import signal
import sys
from typing import NoReturn

EXIT_INTERRUPTED = 130  # as the command line exits on Ctrl-C once it runs


def _interrupted_while_starting(signum: int, frame: object) -> NoReturn:
    print("hoap-actions: interrupted while starting; nothing was written", file=sys.stderr)
    raise SystemExit(EXIT_INTERRUPTED)


def run() -> int:
    """The command line, with Ctrl-C or SIGTERM during its second of imports ending it as during its
    work (exit 130, one line, no traceback) instead of by the signal itself. A signal the process was
    started ignoring (SIGINT for a background job of a non-interactive shell) stays ignored throughout."""
    handlers = {sig: signal.signal(sig, _interrupted_while_starting) for sig in (signal.SIGINT, signal.SIGTERM)
                if signal.getsignal(sig) is not signal.SIG_IGN}
    try:
        from hoap_actions.apps.cli import main
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
    return main()


if __name__ == "__main__":
    sys.exit(run())
