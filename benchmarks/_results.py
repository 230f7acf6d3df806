"""What every benchmark shares: where its figures go (a JSON file under ``benchmarks/results/``), the
options every script takes (``--output``, and ``--data`` / ``--threads`` where it needs them), the
software and machine they were measured with, the recordings it needs (under ``data/``, made on
demand) and how a figure's spread over several recordings is reported. What each benchmark
measures, its current figures and their history: ``docs/experiments/``."""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import warnings
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
DATA = Path(__file__).resolve().parents[1] / "data"
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def arguments(output: str, data: bool = False, threads: bool = False) -> argparse.ArgumentParser:
    """A parent parser with the options benchmarks share: ``--output`` (default ``RESULTS/<output>``);
    with ``data``, ``--data``, the folder recordings are found in or made in (default the checkout's
    ``data/``); with ``threads``, ``--threads``, the BLAS threads (default 1, see :func:`use_blas_threads`)."""
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--output", type=_writable_path, default=RESULTS / output,
                        help="JSON file to write (default: %(default)s)")
    if data:
        parser.add_argument("--data", type=Path, default=DATA,
                            help="folder of recordings, made there when missing (default: %(default)s)")
    if threads:
        parser.add_argument("--threads", type=int, default=1, help="BLAS threads (default: %(default)s)")
    return parser


def _writable_path(text: str) -> Path:
    """``--output`` checked before the run, not after it: its folder is made now and must be writable."""
    path = Path(text)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"cannot make the folder of {path}: {exc.strerror}") from None
    if not os.access(path.parent, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise argparse.ArgumentTypeError(f"cannot write {path}")
    return path


def use_blas_threads(threads: int) -> None:
    """Ask BLAS for ``threads`` threads; this works only before numpy is first imported (a warning says
    so otherwise). On a shared 2-core machine multithreaded BLAS on small products is slower and
    erratic, hence the default of 1."""
    if "numpy" in sys.modules:
        warnings.warn(f"numpy is already imported: BLAS keeps its threads, not {threads}", stacklevel=2)
    for variable in BLAS_THREAD_VARIABLES:
        os.environ[variable] = str(threads)


def ensure_recording(preset: str, seed: int, data: Path, noise: str = "none", workers: int = 1,
                     demonstrator: str = "reference") -> Path:
    """``data/<preset>-s<seed>.h5`` (with ``-<demonstrator>`` and ``-<noise>`` before the suffix for another
    demonstrator or a noisy one), recorded first if it is not there (same arguments, same file)."""
    tag = "" if demonstrator == "reference" else f"-{demonstrator}"
    tag += "" if noise == "none" else "-" + noise.replace("=", "").replace(",", "-")
    path = Path(data) / f"{preset}-s{seed}{tag}.h5"
    if not path.exists():
        from hoap_actions.demonstration.recording import record

        record(preset, path, seed=seed, noise=noise, workers=workers, demonstrator=demonstrator)
    return path


def spread(values: list[float]) -> dict:
    """Mean, standard deviation, 95 % t-interval of the mean, and the values themselves."""
    import numpy as np
    from scipy import stats

    x = np.asarray(values, dtype=float)
    mean = float(x.mean())
    sd = float(x.std(ddof=1)) if len(x) > 1 else 0.0
    half = float(stats.t.ppf(0.975, len(x) - 1) * sd / np.sqrt(len(x))) if len(x) > 1 else float("nan")
    return {"mean": mean, "sd": sd, "ci95": [mean - half, mean + half], "n": len(x), "values": x.tolist()}


def numeric_environment(blas_threads: int | None, **versions: str) -> dict:
    """What timings and results depend on: BLAS threads (None: the library's default), CPUs and the
    1-minute load average when measured, the platform, Python and numpy versions (and ``versions`` of
    other libraries the benchmark uses), and the UTC time of the run."""
    import numpy as np

    return {"blas_threads": blas_threads, "cpu_count": os.cpu_count(), "load_average_1min": os.getloadavg()[0],
            "platform": platform.platform(), "python": sys.version.split()[0], "numpy": np.__version__,
            **versions, "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")}


def write_json(path: Path, document: dict) -> None:
    """Write ``document`` to ``path`` (indented JSON, parent folders made) and say where."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=2) + "\n")
    print(f"wrote {path}")
