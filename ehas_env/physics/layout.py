"""Names and positions shared by every compiled model: baseline states, outputs, baseline slots.

A model's full layout (its effects' parameter slots and extra states appended
after these) is made by :mod:`ehas_env.physics.codegen`; the baseline part
below never moves, so code that only reads the baseline can use these
constants with any model.

Baseline state vector::

    0 theta   crank angle, rad
    1 omega   crank angular velocity, rad/s
    2 qc      valve no-load flow at the rated drop, m^3/s
    3 qc_dot  its derivative, m^3/s^2
    4 pa      chamber A pressure, Pa
    5 pb      chamber B pressure, Pa
    6 ps      supply pressure, Pa (changes only with a supply effect)
    7 xp      piston position, m (r sin(theta) - piston_offset, but with a rod-joint effect a state of its own)
    8 vp      piston velocity, m/s (integrated only with a rod-joint effect)
    9 theta_a armature (torque-motor) rotation, rad    } white-box valve only
   10 omega_a its rate, rad/s                          }

Examples
--------
>>> from ehas_env.physics import layout
>>> layout.STATE_NAMES[layout.S_PA], layout.BASE_SLOTS[layout.I_AREA]
('pa', 'area')
"""
from __future__ import annotations

import math

STATE_NAMES = ("theta", "omega", "qc", "qc_dot", "pa", "pb", "ps", "xp", "vp", "theta_a", "omega_a")
N_BASE_STATES = len(STATE_NAMES)
S_THETA, S_OMEGA, S_QC, S_QCD, S_PA, S_PB, S_PS, S_XP, S_VP, S_THA, S_OMA = range(N_BASE_STATES)

#: baseline parameter slots, SI (rig.RigParams, white_box_valve.WhiteBoxValve.kernel_slots, plant constants)
BASE_SLOTS = (
    "inertia",  # kg m^2
    "radius",  # m
    "area",  # m^2
    "half_stroke",  # m
    "supply",  # Pa, supply pressure (relief setting with a dynamic supply)
    "rated_drop",  # Pa
    "beta",  # Pa
    "dead_volume",  # m^3
    "K",  # m^3/s per mA (converted from LPM/mA)
    "wn",  # rad/s
    "zeta",  # -
    "i_max",  # mA
    "tau",  # s, transport delay of the command (0 on the book's rig)
    "v_tanh",  # m/s, velocity scale of friction sign functions (reference model: 1 mm/s)
    "valve_model",  # 0: identified grey box (K, wn, zeta), 1: white box
    "wb_Kt",  # N m/mA, torque-motor gain
    "wb_Kw",  # N m/m, feedback-wire torque per spool displacement
    "wb_Kf",  # N m/rad, armature stiffness
    "wb_Ja",  # kg m^2, armature-flapper inertia
    "wb_Ba",  # N m s/rad, armature damping
    "wb_r",  # m, lever from the armature pivot to the nozzles
    "wb_Av",  # m^2, spool end area
    "wb_K2",  # m^2/s, nozzle-flapper flow gain at wb_p_ref
    "wb_p_ref",  # Pa, pilot supply at which wb_K2 holds
    "wb_K3",  # m^2/s, spool flow gain at the rated drop
    "wb_xf0",  # m, null nozzle-flapper gap
    "wb_kff",  # m, steady flow force coefficient 0.43 w (F = kff dP x_v)
    "wb_bff",  # N s/(m sqrt(Pa)), transient flow force coefficient Cd w L sqrt(2 rho)
    "wb_AN",  # m^2, nozzle area (pilot pressure force on the flapper)
    "wb_kjet",  # m, flapper jet negative spring 8 pi Cdf^2 x_f0 (k = kjet Ps)
    "wb_xv_max",  # m, spool stops
    "effects_on",  # 1 when any effect with terms is on (0: the baseline's short path, fewer branches per step)
    "piston_offset",  # m, the piston sits at r sin(theta) - piston_offset: a crank arm off the perpendicular at
    # mid-stroke by phi0 gives r sin(phi0) (0 on the book's rig; hyp_crank_offset opens it)
)
N_BASE_SLOTS = len(BASE_SLOTS)
(I_INERTIA, I_RADIUS, I_AREA, I_HALF_STROKE, I_SUPPLY, I_DROP, I_BETA, I_VDEAD, I_K, I_WN, I_ZETA, I_IMAX, I_TAU,
 I_VTANH, I_VALVE_MODEL, I_WB_KT, I_WB_KW, I_WB_KF, I_WB_JA, I_WB_BA, I_WB_R, I_WB_AV, I_WB_K2, I_WB_PREF, I_WB_K3,
 I_WB_XF0, I_WB_KFF, I_WB_BFF, I_WB_AN, I_WB_KJET, I_WB_XVMAX, I_EFFECTS_ON, I_XOFF) = range(N_BASE_SLOTS)
WHITE_BOX = 1.0  # valve_model value of the white-box valve
#: after the effects' slots, every generated model lists the states its integrator moves: ``moved.n`` (how many;
#: 0, unset: all) and ``moved.<a>`` (which), written by ``effects.base.mark_effects_on`` (ehas_env.physics.codegen)
MOVED = "moved."

# Output channels written by the simulators (SI).  theta/omega are what the LVDT
# sees (piston position through asin(x/r)); theta_sensed is the controller's
# reading of it in degrees (noise, gain error, ADC).
OUT_NAMES = ("theta", "omega", "flow_a", "pa", "pb", "ps", "force", "theta_crank", "current", "stroke_end",
             "theta_sensed")
N_OUT = len(OUT_NAMES)
O_THETA, O_OMEGA, O_FLOW, O_PA, O_PB, O_PS, O_FORCE, O_CRANK, O_CURRENT, O_STROKE, O_SENSED = range(N_OUT)
#: the outputs a rig's sensors read from the model's state, each a *reading place* of the model: ``measure``
#: (:mod:`ehas_env.physics.integrator`) passes the output through the generated chain ``<output>_reading``, where
#: an effect's term may change what the sensor reports (an offset, a lag of the reading): output name ->
#: (the argument a term gets, its SI unit, its rate in the right-hand side's terms -- the state-rates quantity
#: ``<argument>_rate``, "" when the model has none --, the sensor in words, its typical span in the SI unit).
#: The position sensor, whose reading the controller also sees, is the place ``position_reading`` of its own.
#: A new sensed output is one entry here and one line of ``measure``.
SENSED = {
    "pa": ("pa", "Pa", "ds[4]", "chamber A's pressure reading", 1.0e7),
    "pb": ("pb", "Pa", "ds[5]", "chamber B's pressure reading", 1.0e7),
    "ps": ("ps", "Pa", "ds[6]", "the supply pressure's reading", 1.0e7),
    "flow_a": ("q", "m^3/s", "", "the flow meter's reading (line A)", 25.0 / 60000.0),
    "force": ("f", "N", "A * (ds[4] - ds[5])", "the load reading (A (P_A - P_B))", 5.0e4),
}
#: the sensed outputs' rates a state's rate may take (``<argument>_rate``: where the model has one)
RATE_QUANTITIES = tuple(f"{arg}_rate" for arg, _, rate, _, _ in SENSED.values() if rate)


def history_length(tau_max: float, dt: float) -> int:
    """Ring-buffer length that covers a command delay of ``tau_max`` s at control period ``dt`` s."""
    return int(math.ceil(max(tau_max, 0.0) / dt)) + 2
