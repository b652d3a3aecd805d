"""Is the run closed-loop?  Evidence that the input depends on the output's past.

An output-error fit assumes the input does not depend on the noise.  Under
feedback (a controller closing the loop through the measured output) the
input carries the past noise and the estimate is biased.  Two kinds of
evidence are looked for:

* the run's sidecar (``RUN.json``) says ``"kind": "closed_loop"`` or names
  a ``controller``;
* the cross-correlation of the residuals with the input at **negative**
  lags and at lag 0 (the input following the residual: R_eu(tau) = sum
  e(k + tau) u(k), tau <= 0; lag 0 because a rig's controller computes u_k
  from y_k, and the models fitted here have no direct term) leaves its 99 % band at more lags than chance allows (1 in 100)
  or at any lag by half the band again (z = 3.9: 1 in 10 000 per lag for an
  open loop) - MATLAB ``resid``'s feedback reading.

What to do: identify from an open-loop run (``ehas excite chirp`` into the
valve), or, if the loop cannot be opened, with an instrumental-variable
method whose instrument is the reference (independent of the noise).

Examples
--------
>>> rng = np.random.default_rng(0)
>>> from ehas_env.identification.fit import residual_analysis
>>> e = rng.normal(size=5000)
>>> closed_loop_evidence(residual_analysis(e, rng.normal(size=5000)))["suspected"]
False
>>> u = np.r_[0.0, -0.8 * e[:-1]] + 0.1 * rng.normal(size=5000)   # the input reacts to the last residual
>>> closed_loop_evidence(residual_analysis(e, u))["suspected"]
True
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

ADVICE = ("identify from an open-loop run (ehas excite chirp into the valve), or use an instrumental-variable "
          "method with the reference as instrument")


def sidecar_of(run) -> dict | None:
    """The run's ``RUN.json`` sidecar as a dict, or None (missing or unreadable: no evidence either way)."""
    p = Path(run).with_suffix(".json")
    if not p.is_file():
        return None
    try:
        doc = json.loads(p.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return doc if isinstance(doc, dict) else None


def closed_loop_evidence(ra, sidecar: dict | None = None) -> dict:
    """``{"suspected": bool, "reasons": [...], "advice": str}`` from a residual analysis and the sidecar.

    Parameters
    ----------
    ra : ResidualAnalysis
        Of the fit's residuals and its input.
    sidecar : dict, optional
        The run's sidecar.

    Returns
    -------
    dict
    """
    reasons = []
    if sidecar:
        if sidecar.get("kind") == "closed_loop":
            reasons.append("the sidecar says kind = closed_loop")
        elif sidecar.get("controller"):
            reasons.append("the sidecar names a controller")
    neg = ra.cross_lags <= 0
    outside = int(np.sum(np.abs(ra.cross[neg]) > ra.cross_band))
    allowed = max(1, round(0.01 * int(neg.sum())))
    peak = float(np.max(np.abs(ra.cross[neg]))) if neg.any() else 0.0
    if outside > allowed or peak > 1.5 * ra.cross_band:
        reasons.append(f"the input follows the residual at {outside} lags <= 0 (99 % band; peak "
                       f"{peak / ra.cross_band:.1f} x the band)")
    return {"suspected": bool(reasons), "reasons": reasons, "advice": ADVICE, "lags_le_0_outside": outside}


def warning_line(evidence: dict) -> str:
    """One line: what suggests feedback and what to do."""
    return (f"warning: the run looks closed-loop ({'; '.join(evidence['reasons'])}): an output-error fit is biased "
            f"by feedback; {evidence['advice']}")
