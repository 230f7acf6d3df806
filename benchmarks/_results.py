"""Where a benchmark's figures go: a JSON file (under ``benchmarks/results/``) and the software they
were measured with."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path


def numeric_environment(blas_threads: int) -> dict:
    """BLAS threads, CPUs, Python and numpy versions: what numeric timings and results depend on."""
    import numpy as np

    return {"blas_threads": blas_threads, "cpu_count": os.cpu_count(), "python": sys.version.split()[0],
            "numpy": np.__version__}


def write_json(path: Path, document: dict) -> None:
    """Write ``document`` to ``path`` (indented JSON, parent folders made)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(document, indent=2) + "\n")
