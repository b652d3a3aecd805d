"""A proposed term never holds forms that cancel one another (issue 43: the tool names physics, never invents it).

Independent truth: the independent generator's (``tests/independent_rig``, sharing no code with the package) end
cushion, a damper acting near the stroke ends, every closed-loop run started from rest.  A damper takes energy out
of the motion, so a form the proposal keeps for it opposes the motion: a negative coefficient of theta^2 omega at
the crank or of x^2 v at the piston.  A torque at the crank and a force on the piston are one load through the
lever r cos(theta), so each form at one place has a near twin at the other (their responses correlate 0.99 and
more); fitted together, their coefficients grow apart in sign until only their small difference fits the data --
on this campaign +2.4e7 N s/m^3 at the piston (feeding energy in) against -124 N m s/rad^3 at the crank, a sum 7 %
of the parts.  The proposal refuses such a set (:data:`~ehas_env.diagnosis.proposal.CANCEL_SHARE`), and its sparse
regression keeps one of two twins (:data:`~ehas_env.diagnosis.proposal.TWIN_R`); with both rules off the test fails
(seen).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ehas_env.diagnosis import fitting as D
from ehas_env.diagnosis import proposal as P
from ehas_env.measurement.campaign import read_campaign
from ehas_env.measurement.replay import ModelSpec, Replayer

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.independent_rig import campaign as gen  # noqa: E402
from tests.independent_rig.start_conditions import options  # noqa: E402

#: the damping forms of the two places (their coefficient is negative for a damper)
DAMPING = {"proposal_crank_torque.c_th2w", "proposal_piston_force.c_x2v", "proposal_crank_torque.c_w",
           "proposal_piston_force.c_v", "proposal_crank_torque.c_ww", "proposal_piston_force.c_vv"}


def test_a_dampers_proposal_keeps_no_forms_that_cancel(tmp_path):
    runs, truth = gen.simulate({"end_cushion": {"ce": 40000.0}}, seed=902, rig="book", duration=2.0,
                               **options("rest", "book", 2.0))
    rep = Replayer(read_campaign(gen.write(tmp_path / "camp", runs, truth, overwrite=True)))
    model = ModelSpec(beta=truth["beta_Pa"], K=truth["K_lpm_per_mA"])
    sims = rep.simulate(model)
    base = D.Fit(model=model, cost=D.replay_cost(rep, sims), free=[], sims=sims, table=rep.fit_table(sims))
    prop = P.propose(rep, base, name=False)
    assert prop is not None and prop.cost_after < base.cost
    damping = {k: c for k, c in prop.terms.items() if k in DAMPING}
    assert damping, prop.terms  # the cushion is found as a damping
    assert all(c < 0.0 for c in damping.values()), prop.terms  # each of them takes energy out of the motion
    # the set the sparse regression and the fit would have kept is on record as refused, with its small sum
    assert all(r["net_share"] < P.CANCEL_SHARE for r in prop.cancelling)
    # the sparse regression holds no two forms whose features the campaign cannot part
    keys = list(prop.sparse)
    feats = {k: np.concatenate([P.force_feature(k, P.si_quantities(c, s)) for c, s in P._force_cases(rep, sims)])
             for k in keys}
    assert P.without_twins(feats) == keys
