"""The compiled model's right-hand side against the plain-Python twin, at one state."""
from __future__ import annotations

import numpy as np

from ehas_env.physics.reference_rhs import rhs as reference_rhs


def assert_rhs_matches_twin(plant, state, i_valve: float) -> np.ndarray:
    """Compiled ``derivatives`` of ``plant``'s own model at ``state`` (padded with zeros) equal the twin's.

    Returns the compiled rates.
    """
    m = plant.model
    s = np.zeros(m.N_STATES)
    s[:len(state)] = state
    ds = np.zeros(m.N_STATES)
    m.derivatives(s, i_valve, plant.param_vector, ds)
    ref = reference_rhs(dict(zip(m.STATE_NAMES, s)), i_valve, plant.slots())
    expected = np.array([ref[name] for name in m.STATE_NAMES])
    np.testing.assert_allclose(ds, expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())
    return ds
