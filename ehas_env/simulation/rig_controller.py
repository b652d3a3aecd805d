"""The book's PI + feed-forward controller: its gains and its compiled law, one class.

:class:`RigController` holds the gains (units in
:data:`~ehas_env.simulation.pi_ff_law.GAIN_UNITS`) of the law
:func:`~ehas_env.simulation.pi_ff_law.pi_ff_law`, which the compiled model runs
(``law_id()``, ``gains_vector()``).  :class:`ehas_controllers.piff.PIFF` is this
class with the controller protocol added (output limit, DAC, name, JSON file,
``act`` in Python).

Examples
--------
>>> from ehas_env.simulation.rig_controller import RigController
>>> c = RigController.book()
>>> round(c.Kv, 6), c.law_id()
(0.017778, 0)
>>> print(c.gains_vector()[:3])
[1.         2.         0.01777778]
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ehas_env.ranges import check_field
from ehas_env.simulation.control_laws import N_GAINS, law_id
from ehas_env.simulation.pi_ff_law import GAIN_NAMES


@dataclass
class RigController:
    """The rig's RMC70-like controller: PI + velocity/acceleration feed-forward.

    ``i = Kp e + Ki int(e) + Kv theta_ref' + Ka theta_ref'' [+ Kj theta_ref''' - Kdp dP_L]``
    on theta in degrees, sampled at ``rate_hz`` with zero-order hold, output
    clipped to +-20 mA with anti-windup.

    Attributes
    ----------
    Kp : float
        mA/deg.
    Ki : float
        mA/(deg s).
    Kv : float
        mA/(deg/s), velocity feed-forward.
    Ka : float
        mA/(deg/s^2), acceleration feed-forward.
    Kj : float
        mA/(deg/s^3), jerk feed-forward (model inversion of the valve lag; 0 on the rig).
    Kdp : float
        mA/bar, load-pressure feedback (0 on the rig).
    dp_hp : float
        rad/s, corner of the pressure feedback's high-pass (0: static feedback).
    rate_hz : float
        Controller rate, Hz (rig: 1 kHz).
    """

    Kp: float = 1.0
    Ki: float = 2.0
    Kv: float = 1.0 / 56.25
    Ka: float = (1.0 / 56.25) * 2.0 * 0.691 / 107.0
    Kj: float = 0.0
    Kdp: float = 0.0
    dp_hp: float = 0.0
    rate_hz: float = 1000.0

    @classmethod
    def book(cls) -> "RigController":
        """The reference model's classical baseline: Kp 1, Ki 2, Kv 1/56.25, Ka = Kv 2 zeta / wn.

        Returns
        -------
        RigController
            The book's gains (the class defaults): Kp 1 mA/deg, Ki 2 mA/(deg s), Kv 1/56.25 mA/(deg/s),
            Ka = Kv 2 (0.691) / 107 mA/(deg/s^2), no jerk or pressure feedback, 1 kHz.
        """
        return cls()

    def gains_vector(self) -> np.ndarray:
        """The compiled law's gains (:data:`GAIN_NAMES` in order), padded to ``control_laws.N_GAINS``.

        Returns
        -------
        ndarray
            ``Kp, Ki, Kv, Ka, Kj, Kdp, dp_hp`` in the units of
            :data:`~ehas_env.simulation.pi_ff_law.GAIN_UNITS` (mA/deg, ..., rad/s), then zeros up to
            ``N_GAINS`` entries.
        """
        g = np.zeros(N_GAINS)
        g[:len(GAIN_NAMES)] = [getattr(self, k) for k in GAIN_NAMES]
        return g

    @staticmethod
    def law_id() -> int:
        """Number of the compiled law (PI + feed-forward, :func:`~ehas_env.simulation.pi_ff_law.pi_ff_law`).

        Returns
        -------
        int
            The id under which :mod:`ehas_env.simulation.control_laws` registered the law ``"pi_ff"`` (0).
        """
        return law_id("pi_ff")

    def to_dict(self) -> dict:
        """The gains as a plain dict.

        Returns
        -------
        dict
            Field name -> value (``Kp``, ``Ki``, ``Kv``, ``Ka``, ``Kj``, ``Kdp``, ``dp_hp``, ``rate_hz``),
            in the units of the class's Attributes.
        """
        return asdict(self)

    def __post_init__(self):
        for name, value in asdict(self).items():
            check_field("rate_hz" if name == "rate_hz" else "gain", value, f"RigController: {name}")
