"""What every benchmark shares: where its figures go (a JSON file under ``benchmarks/results/``), the
software they were measured with, the recordings it needs (under ``data/``, made on demand) and how
a figure's spread over several recordings is reported."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path


RESULTS = Path(__file__).resolve().parent / "results"


def ensure_recording(preset: str, seed: int, data: Path) -> Path:
    """``data/<preset>-s<seed>.h5``, recorded first if it is not there (same preset and seed, same file)."""
    path = Path(data) / f"{preset}-s{seed}.h5"
    if not path.exists():
        from hoap_actions.envs.recording import record

        record(preset, path, seed=seed)
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


def numeric_environment(blas_threads: int | None) -> dict:
    """BLAS threads, CPUs, Python and numpy versions: what numeric timings and results depend on."""
    import numpy as np

    return {"blas_threads": blas_threads, "cpu_count": os.cpu_count(), "python": sys.version.split()[0],
            "numpy": np.__version__}


def write_json(path: Path, document: dict) -> None:
    """Write ``document`` to ``path`` (indented JSON, parent folders made)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=2) + "\n")
