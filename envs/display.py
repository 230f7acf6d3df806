"""Whether PyBullet's GUI can open a window here, asked before it is started (it ends the process when it cannot)."""

from __future__ import annotations

import os
import subprocess
import sys

from hoap_actions.errors import DisplayUnavailableError

__all__ = ["X_PROBE_TIMEOUT_S", "check_display"]

_X_PROBE = """
import ctypes, ctypes.util, os, sys
library = ctypes.util.find_library("X11")
if library is None:
    sys.exit(3)
xlib = ctypes.CDLL(library)
xlib.XOpenDisplay.restype = ctypes.c_void_p
xlib.XOpenDisplay.argtypes = [ctypes.c_char_p]
xlib.XQueryExtension.argtypes = [ctypes.c_void_p, ctypes.c_char_p] + [ctypes.POINTER(ctypes.c_int)] * 3
xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
display = xlib.XOpenDisplay(os.environ["DISPLAY"].encode())
if not display:
    sys.exit(4)
codes = [ctypes.c_int() for _ in range(3)]
has_glx = xlib.XQueryExtension(display, b"GLX", *(ctypes.byref(c) for c in codes))
xlib.XCloseDisplay(display)
sys.exit(0 if has_glx else 5)
"""
"""Asks the X server named by DISPLAY, through Xlib, whether PyBullet's window can open there. It runs
in a child process: Xlib used in this process before PyBullet's window thread made that thread's own
connection fail under Xvfb in 4 of 8 runs of three window starts (3 of 10 with XInitThreads called first)."""
X_PROBE_TIMEOUT_S = 10.0


def check_display() -> None:
    """Raise :class:`DisplayUnavailableError` unless PyBullet's GUI can open a window here.

    On Linux PyBullet's GUI ends the whole process (exit 1, no exception) when it cannot reach an X
    server or the server has no OpenGL (GLX); so ask the X server first (:data:`_X_PROBE`). Other
    platforms open native windows and are not checked.
    """
    if not sys.platform.startswith("linux"):
        return
    hint = "use render_mode='rgb_array' (headless), or run under a virtual X server (xvfb-run)"
    name = os.environ.get("DISPLAY")
    if not name:
        raise DisplayUnavailableError(f"render_mode='human' needs a display, but DISPLAY is not set; {hint}")
    try:
        probe = subprocess.run([sys.executable, "-c", _X_PROBE], timeout=X_PROBE_TIMEOUT_S, capture_output=True)
        code = probe.returncode
    except subprocess.TimeoutExpired:
        code = 4
    if code == 3:
        raise DisplayUnavailableError(f"render_mode='human' needs the X11 library (libX11), which is not installed; "
                                      f"{hint}")
    if code == 4:
        raise DisplayUnavailableError(f"render_mode='human' cannot open the X display DISPLAY={name!r}; {hint}")
    if code == 5:
        raise DisplayUnavailableError(f"the X display {name!r} has no OpenGL (GLX extension), which PyBullet's GUI "
                                      f"needs; {hint}")
    if code != 0:
        raise DisplayUnavailableError(f"checking the X display {name!r} failed (exit {code}); {hint}")
