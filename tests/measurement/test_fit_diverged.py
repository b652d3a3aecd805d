"""A candidate whose replay diverges does not stop the fit (found on the start-conditions backlash campaign at
633a0e8: a sparse start of thirteen terms, a negative damping of 1.4e5 N s/m on the piston among them, made a
forward-difference step's replay diverge, and the diagnosis ended "array must not contain infs or NaNs").

Independent truth: a residual written here in numpy, r(p) = p - 3 (in noise units), whose "replay" is not finite
beyond p = 5; the least-squares fit from p = 4.99 must step away from the divergence and land on p = 3.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from ehas_env.diagnosis import fitting as D


class _Rep:
    """A replayer of one block, r = p - 3 on 50 samples, NaN where p > 5 (the replay diverged)."""

    n_evals = 0

    def simulate_many(self, models):
        self.n_evals += len(models)
        return [m.terms["p"] for m in models]

    def cost_blocks(self, p):
        r = np.full(50, p - 3.0) + 0.01 * np.sin(np.arange(50))
        return [r if p <= 5.0 else np.full(50, np.nan)]

    def fit_table(self, sims):
        return SimpleNamespace(overall=0.0)


def test_a_diverged_replay_is_a_large_residual_not_a_stop():
    fp = D.FreeParam(D.TERM, "p", 0.0, 10.0, False, step=2e-3)
    rep = _Rep()
    f = D.fit(rep, [fp], {(D.TERM, "p"): 4.999}, max_nfev=40)  # its first difference step replays beyond 5
    assert math.isfinite(f.cost)
    assert abs(f.model.terms["p"] - 3.0) < 0.05
    assert D.finite_blocks([np.array([1.0, np.inf])])[0][1] == D.DIVERGED
