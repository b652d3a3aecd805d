"""Progress totals are fixed before they are shown (issue 36: a diagnosis' bar went 13/16 -> 13/14).

The screening's count is known at the start, the refinements' only after the screening: one bar per
stage, each created with its final total.  The fits are replaced by stand-ins with set costs (what is
checked is the bars, not the fits); every bar records each total it showed.
"""
from __future__ import annotations

from types import SimpleNamespace

import pytest

import ehas_env.diagnosis.candidates as D
from ehas_env.measurement.replay import ModelSpec


class RecordingBar:
    """A tqdm stand-in that records the totals it was shown with."""

    made: list = []

    def __init__(self, total=None, **kw):
        self.total, self.n, self.shown = total, 0, [total]
        self.desc = kw.get("desc", "")
        RecordingBar.made.append(self)

    def __bool__(self):
        return True

    def update(self, k=1):
        self.n += k
        self.shown.append(self.total)

    def refresh(self):
        self.shown.append(self.total)

    def close(self):
        self.shown.append(self.total)


def fit(cost, effects=None):
    return SimpleNamespace(cost=cost, model=ModelSpec(effects=effects or {}), free=[], sims=[],
                           table=SimpleNamespace(overall=90.0))


@pytest.mark.parametrize("screened, refined", [
    # three within 3 dB of the best (REFINE_WITHIN_DB) and one that does not help: 4 screened, 3 refined
    ({"coulomb_friction": 0.5, "viscous_friction": 0.52, "internal_leakage": 0.9, "external_leakage": 1.0}, 3),
    ({"coulomb_friction": 0.1, "viscous_friction": 0.9}, 1),  # the second is 9.5 dB behind: only the best
    ({"coulomb_friction": 1.0, "viscous_friction": 1.0}, 0),  # nothing helps: no refinement bar at all
])
def test_each_bar_keeps_the_total_it_started_with(monkeypatch, screened, refined):
    import tqdm

    RecordingBar.made = []
    monkeypatch.setattr(tqdm, "tqdm", RecordingBar)
    rep = SimpleNamespace(simulate=lambda spec: [], log_cost=lambda sims: 1.0,
                          fit_table=lambda sims: SimpleNamespace(overall=80.0), n_evals=0, cases=[])
    monkeypatch.setattr(D, "fit_null", lambda rep, base: fit(1.0))
    monkeypatch.setattr(D, "screen_candidate", lambda rep, n, null, fits: fit(screened[n], {n: {}}))
    monkeypatch.setattr(D, "refine_candidate", lambda rep, n, f, null, base: fit(f.cost * 0.9, {n: {}}))
    monkeypatch.setattr(D, "evidence_text", lambda rep, null, e: "")
    D.diagnose(None, candidates=list(screened), progress=True, replayer=rep)
    bars = RecordingBar.made
    assert [b.desc for b in bars] == ["diagnose: screening"] + (["diagnose: refining"] if refined else [])
    assert bars[0].shown == [len(screened)] * len(bars[0].shown) and bars[0].n == len(screened)
    if refined:
        assert set(bars[1].shown) == {refined} and bars[1].n == refined
