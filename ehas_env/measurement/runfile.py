"""Writing one run in the measurement format (CSV + JSON sidecar).

The format is the project's measurement contract (README, "Measurement files"):
``RUN.csv`` with a header line and one row per sample, and ``RUN.json`` saying
what the run was.  Reading and validating campaigns lives in ``ehas_env.measurement.campaign``.
"""
from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from ehas_env.output.files import atomic_write_text

#: column order used when writing (readers accept any order)
COLUMN_ORDER = ("t", "current_mA", "theta_deg", "theta_ref_deg", "flow_lpm", "p_a_bar", "p_b_bar", "p_s_bar", "load_kN")


def write_run(stem, columns: dict[str, np.ndarray], meta: dict) -> tuple[Path, Path]:
    """Write ``stem.csv`` and ``stem.json`` atomically; return their paths.

    ``columns`` maps column names of the format to equal-length arrays; NaN is
    written as an empty cell (a missing sample).
    """
    stem = Path(stem)
    if stem.suffix in (".csv", ".json"):
        stem = stem.with_suffix("")
    names = [c for c in COLUMN_ORDER if c in columns] + [c for c in columns if c not in COLUMN_ORDER]
    data = np.column_stack([np.asarray(columns[c], dtype=float) for c in names])
    buf = io.StringIO()
    buf.write(",".join(names) + "\n")
    for row in data:
        buf.write(",".join("" if not np.isfinite(v) else f"{v:.10g}" for v in row) + "\n")
    csv_path = atomic_write_text(stem.with_suffix(".csv"), buf.getvalue())
    json_path = atomic_write_text(stem.with_suffix(".json"), json.dumps(meta, indent=2, sort_keys=False) + "\n")
    return csv_path, json_path
