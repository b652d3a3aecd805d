"""A model of every effect skips the work of the effects that are off, and no number moves.

The model a diagnosis replays holds every effect and structural hypothesis (52 states); a replay has one to three
of them on.  ``mark_effects_on`` writes, beside the effects' on-flags, one all-off slot per place (the model passes
a place's list of on-checks with one test when every effect there is off) and the list of the states the
integrator moves (the baseline's and those of the effects on; an effect that is off has rates 0, so its states'
RK4 sums add 0).  These tests hold the skipping to the arithmetic it skips: bit for bit the run of the model of
just those effects, and the run of the same vector with nothing marked skippable.
"""
from __future__ import annotations

import numpy as np
import pytest

from ehas_env.physics import layout
from ehas_env.physics.effects import REGISTRY
from ehas_env.physics.effects.base import mark_effects_on
from ehas_env.simulation.plant import Plant

#: one effect of each kind of work skipped: a balance's term, a hose (states, the chambers' flows, the ports'
#: pressures), a follower of the flow meter (its states follow the metered flow), the coil's rate limit
EFFECTS = {"coulomb_friction": {"Fc": 300.0}, "aug_hose_b": {"V_line": 40.0, "R_line": 0.5},
           "aug_lag_flow_a_reading": {"T": 3.0}, "aug_slew_coil": {"S": 2000.0}}


def _chirp(n: int = 1500, dt: float = 1e-3) -> np.ndarray:
    t = np.arange(n) * dt
    return 6.0 * np.sin(2.0 * np.pi * (1.0 + 6.0 * t) * t)


def _run(model, slots: dict, s0: dict, plant) -> np.ndarray:
    """The open-loop chirp on ``model`` with the named ``slots`` (marked for it) from the named state ``s0``."""
    named = mark_effects_on(dict(slots), model)
    P = np.array([named.get(n, 0.0) for n in model.SLOTS])
    s = np.array([s0.get(n, 0.0) for n in model.STATE_NAMES])
    out = np.zeros((1500, layout.N_OUT))
    model.run_open_loop(s, P, _chirp(), plant.dt, plant.substeps, np.zeros(64), out)
    return out


def test_a_model_of_every_effect_runs_the_effects_on_as_their_own_model_does():
    from ehas_env.physics.codegen import build_model
    from ehas_env.simulation.control_laws import all_laws

    plant = Plant(disc_sets=3, effects=EFFECTS, hypotheses=True)
    own = build_model([REGISTRY[n] for n in EFFECTS], laws=all_laws(), inline=False)
    every = plant.model
    assert every.N_STATES > own.N_STATES and len(every.EFFECTS) > 10 * len(own.EFFECTS)
    slots = plant.slots()
    s0 = dict(zip(every.STATE_NAMES, plant.initial_state()))
    np.testing.assert_array_equal(_run(own, slots, s0, plant), _run(every, slots, s0, plant))


def test_nothing_marked_skippable_gives_the_same_run():
    plant = Plant(disc_sets=3, effects=EFFECTS, hypotheses=True)
    m, P = plant.model, plant.param_vector
    moved = int(P[m.I_MOVED])
    off = [m.IDX[name] for name, _ in m.GROUPS if P[m.IDX[name]] == 1.0]
    assert layout.N_BASE_STATES < moved < m.N_STATES and len(off) > 5  # the marking does skip work here
    unmarked = P.copy()
    unmarked[m.I_MOVED] = 0.0  # a count of 0 moves every state
    unmarked[off] = 0.0  # every place's checks made
    runs = []
    for vector in (P, unmarked):
        out = np.zeros((1500, layout.N_OUT))
        m.run_open_loop(plant.initial_state(), vector, _chirp(), plant.dt, plant.substeps, np.zeros(64), out)
        runs.append(out)
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_an_effect_on_leaves_each_of_its_places_checked_and_its_states_moved(name):
    """With one effect on, none of the places its terms act at is marked all-off and all its states are moved
    (the places and states as the effect declares them, against what the generated model's marking does)."""
    from ehas_env.simulation.compiled_model import current_model

    m = current_model(hypotheses=True)
    slots = mark_effects_on({f"{e}.on": float(e == name) for e in m.EFFECTS}, m)
    cls = REGISTRY[name]
    places = list(cls.terms())  # (an effect that only sets slots, the bulk modulus's, has none)
    if cls.states and "state_rates" in places and "q" in cls.term_args("state_rates"):
        places.append("metered_flow")  # its states follow the flow meter's reading: the metered flow is computed
    for place in places:
        assert slots.get(f"all_off.{place}", 0.0) == 0.0, place
    moved = {int(slots[f"{layout.MOVED}{a}"]) for a in range(int(slots[layout.MOVED + "n"]))}
    own = {m.STATE_NAMES.index(f"{name}.{st[0]}") for st in REGISTRY[name].states}
    assert set(range(layout.N_BASE_STATES)) | own == moved
