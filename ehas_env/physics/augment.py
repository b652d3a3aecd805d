"""Generic state augmentations: one definition per kind of missing state, applied place by place (issue 33, item 2).

A rig always holds something no one listed; much of it is a *state* the baseline lacks.  Four kinds cover the
usual ones (Merritt ch. 5-6; Jelali & Kroll ch. 3), each one class here that holds the kind's parameters (unit,
bounds, doc), its explanation, residual signature and its words; a subclass per *place* holds only the terms that
put the kind's state there:

* **lag** (a first-order filter ``T y' = u - y``) in a signal path: the current at the valve's coil
  (:class:`LagCoil`) and the position sensor's reading (:class:`LagPositionSensor`, an LVDT demodulator's
  filter); and a **rate limit** of the coil's current (:class:`SlewCoil`, an amplifier's voltage headroom);
* **compliance with a mass** in a mechanical link: the rod-crank joint (:class:`LinkRodCrank`, the piston a mass
  of its own on a spring) and the actuator's mount (:class:`LinkMount`, the cylinder's body a mass on a spring);
* **volume with a resistance** in a hydraulic path: a hose between the valve's port and chamber A or B, or a
  pair alike in both lines (:class:`HoseA`, :class:`HoseB`, :class:`HoseAB`: a line pressure state, the valve
  meters against the line's pressure -- and the flow meter at the port sees that flow -- the chamber fills
  through a laminar resistance);
* **play** in a joint: the library's own :mod:`ehas_env.physics.effects.backlash` (rod-crank joint).

They are effects (``kind = "hypothesis"``: they live only in the model with the hypotheses, never in an
environment's), registered when :mod:`ehas_env.physics.effects` is imported; they live outside that package, so
neither the library fit nor the structural-hypothesis stage tries them: the state stage
(:mod:`ehas_env.measurement.state_search`) does, place by place (:func:`augmentations`).

The sensor lag's state is the reading's error (0 at rest, whatever the position a run starts from); a line's
pressure starts at the chambers' initial half supply pressure (:meth:`ehas_env.simulation.plant.Plant.initial_state`)
of the book's rig, and relaxes to its chamber's within a fraction of a millisecond on a rig whose supply differs.
"""
from __future__ import annotations

import math
from typing import ClassVar

from ehas_env.physics.effects.base import Effect, Param
from ehas_env.physics.rig import SUPPLY_PRESSURE

#: 1 bar/(L/min) in Pa s/m^3 (a laminar resistance's engineering unit)
BAR_PER_LPM = 1.0e5 * 60000.0
#: a link's mode, in integrator sub-steps per radian: the mass is held at least k (h MIN_STEPS_PER_RAD)^2 (the
#: explicit RK4 step is stable to 2.8 rad per step; 2.5 sub-steps per radian resolve the mode itself)
MIN_STEPS_PER_RAD = 2.5
#: a hose's relaxation (line and chamber through the resistance), in integrator sub-steps per time constant: the
#: resistance is held at least the value that gives this (RK4 is stable to 1 / 2.78; the relaxation itself is
#: far faster than anything the logs resolve, only its end -- the drop R q -- shows)
MIN_STEPS_PER_TAU = 0.6


def _fmt(v: float, ci, scale: float = 1.0) -> str:
    """``v`` (times ``scale``) with its interval, each to 3 significant digits, or more where the three would
    print the same number."""
    if ci is None or ci[0] is None or not all(math.isfinite(x) for x in ci):
        return f"{v * scale:.3g}"
    for n in range(3, 7):
        lo, mid, hi = (f"{x * scale:.{n}g}" for x in (ci[0], v, ci[1]))
        if len({lo, mid, hi}) == 3 or ci[0] == ci[1]:
            break
    return f"{mid} [{lo}, {hi}]"


class Augmentation(Effect):
    """A generic augmentation: a kind of state (``form``) at a place (``where``).  Not registered itself (no name);
    the kinds below and their places are."""

    kind = "hypothesis"
    #: screened also from its defaults (nearly no effect) when a kept effect re-opened beta or K
    #: (:func:`ehas_env.measurement.diagnosis.screen_candidate`): a state may add what that number took over
    screen_from_defaults: ClassVar[bool] = True
    #: the kind, in words ("a first-order lag")
    form: ClassVar[str] = ""
    #: the place, in words ("the position sensor's reading")
    where: ClassVar[str] = ""
    #: how the words show a parameter: {name: (factor from its unit, unit shown)}
    shown: ClassVar[dict] = {}

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """The fitted augmentation in physical words, with 95 % intervals where given.

        Parameters
        ----------
        params : dict of str to float
            The fitted parameters, in their units.
        ci : dict of str to (float, float), optional
            95 % intervals by parameter name, in their units.

        Returns
        -------
        str
            E.g. "a first-order lag of 4.1 [3.2, 5] ms in the position sensor's reading (corner 39 Hz)".
        """
        ci = ci or {}

        def one(q):
            scale, unit = cls.shown.get(q.name, (1.0, q.unit))
            return f"{_fmt(params[q.name], ci.get(q.name), scale)} {unit}"

        p = cls.params
        rest = "".join(f" and {q.doc.split(':')[0]} {one(q)}" for q in p[1:])
        return f"{cls.form} of {one(p[0])}{rest} in {cls.where}{cls._extra(params)}"

    @classmethod
    def _extra(cls, params: dict) -> str:
        return ""


# -- a lag in a signal path ------------------------------------------------------------------------------------------

class Lag(Augmentation):
    """A first-order lag ``T y' = u - y`` of a signal: what the model passes on is ``y`` instead of ``u``."""

    form = "a first-order lag"
    params = (
        Param("T", "ms", 2.0, (0.05, 50.0),
              "time constant: a filter's, a coil's inductance over its resistance, a demodulator's smoothing "
              "(assumed range: tenths of a ms to tens of ms; Merritt sec. 5.8, an LVDT conditioner's 1-5 ms)",
              typical=(0.5, 8.0), si=1.0e-3, log_scale=True),
    )
    main_param = "T"
    explanation = (
        "A signal passes a first-order filter the model does not hold: T y' = u - y. The output follows the "
        "input's sine with gain 1/sqrt(1 + (w T)^2) and a phase lag atan(w T)."
    )
    signature = (
        "a residual in quadrature with the signal, growing with frequency up to the corner 1/(2 pi T); a "
        "transport delay fitted to it comes out different on slow and fast runs (the lag's phase saturates)."
    )

    @classmethod
    def _extra(cls, params: dict) -> str:
        return f" (corner {1.0 / (2.0 * math.pi * params['T'] * 1e-3):.3g} Hz)"


class LagCoil(Lag):
    """The lag at the valve's coil: the torque motor acts on a lagged current."""

    name = "aug_lag_coil"
    title = "first-order lag in the current path (command to coil)"
    where = "the valve's current path (command to coil)"
    states = (("i_lag", "mA", 0.0),)

    @staticmethod
    def state_rates(i, i_lag, T):
        return (i - i_lag) / T

    @staticmethod
    def coil_current(i_lag):
        return i_lag


class SlewCoil(Augmentation):
    """A rate limit in the current path: the driver cannot make the coil's current change faster than ``S``.

    A servo amplifier drives the torque motor's coil through its inductance with a bounded voltage, so the current
    rises at most (V_max - R i) / L, about constant (Jelali & Kroll 2003, the servo amplifier; Merritt 1967, the
    torque motor).  The state is the current the coil carries, i_c' = S tanh((i - i_c) / (S T_ss)): a first-order
    follower of time constant T_ss for small steps, never faster than S for large ones (tanh keeps the right-hand
    side smooth for the integrator)."""

    name = "aug_slew_coil"
    title = "rate limit in the current path (command to coil)"
    form = "a rate limit"
    where = "the valve's current path (command to coil)"
    shown = {"S": (1.0e-3, "mA/ms")}
    params = (
        Param("S", "mA/s", 2000.0, (20.0, 1.0e5),
              "largest rate of change of the coil's current: the amplifier's voltage headroom over the coil's "
              "inductance (assumed range: 0.02 to 100 mA/ms; a 10 mA coil of 1 H on 10 V headroom: 10 mA/ms)",
              typical=(100.0, 20000.0), log_scale=True),
    )
    constants = (
        Param("T_ss", "s", 1.0e-4, (1.0e-5, 1.0e-2),
              "small-signal time constant of the current loop (assumed: a current-feedback amplifier's 1.6 kHz "
              "bandwidth, faster than anything the 1-3 Hz runs resolve)"),
    )
    main_param = "S"
    states = (("i_coil", "mA", 0.0),)
    explanation = (
        "The coil's current follows the command, but no faster than the rate S the amplifier's voltage can "
        "drive through the coil's inductance: a step or a fast reversal of the command becomes a ramp."
    )
    signature = (
        "a current residual (and a flow and pressure one after it) at the command's fast reversals, growing "
        "with the runs' frequency and amplitude; a small sine is passed unchanged (a lag fitted to it comes out "
        "longer on the fast, large runs)."
    )

    @staticmethod
    def state_rates(i, i_coil, S, T_ss):
        return S * math.tanh((i - i_coil) / (S * T_ss))

    @staticmethod
    def coil_current(i_coil):
        return i_coil


class LagPositionSensor(Lag):
    """The lag at the position sensor: the rig logs (and its loop sees) a filtered reading of the piston.  The
    state is the reading's error e = reading - x: e' = -e / T - v (from T y' = x - y), 0 at rest."""

    name = "aug_lag_position_sensor"
    title = "first-order lag in the position sensor's reading (LVDT demodulator filter)"
    where = "the position sensor's reading"
    #: a lagging reading makes the loop late, as a delay of its command does: the diagnosis fits it in place of a
    #: transport delay it keeps (pressures and flow, which the sensor's lag does not touch, tell them apart)
    mistaken_for = ("transport_delay",)
    states = (("e_read", "m", 0.0),)
    #: after the sensor's static effects (an offset, a shape): the lag filters what the conditioner outputs
    chain_order = 100

    @staticmethod
    def state_rates(v, e_read, T):
        return -e_read / T - v

    @staticmethod
    def position_reading(x, e_read):
        return x + e_read


# -- a compliance with a mass in a mechanical link -------------------------------------------------------------------

class Link(Augmentation):
    """A spring (with light damping) in a mechanical link and the mass on its far side."""

    form = "a spring"
    shown = {"k_link": (1.0e-6, "N/um")}
    params = (
        Param("k_link", "N/m", 2.0e7, (1.0e5, 1.0e9),
              "stiffness: of the link, pin and eye, or of the mount (assumed range: a soft mount of 0.1 N/um to "
              "a stiff steel linkage of 1 kN/um)", typical=(2.0e6, 5.0e7), log_scale=True),
        Param("m_link", "kg", 10.0, (0.5, 500.0),
              "mass: on the spring's free side (the piston and rod, or the cylinder's body; assumed range)",
              typical=(3.0, 40.0), log_scale=True),
    )
    constants = (
        Param("zeta_link", "-", 0.1, (0.0, 10.0), "damping ratio of the spring with its mass (assumed)"),
    )
    main_param = "k_link"
    explanation = (
        "The baseline's links are rigid. A spring k_link with a mass m_link on its free side makes a mode of "
        "its own at sqrt(k_link / m_link), damped lightly (damping ratio 0.1, assumed)."
    )
    signature = (
        "position residual in phase with the load force (the link yields by F / k_link); ringing in the "
        "pressures at sqrt(k_link / m_link) after reversals; more on the heavy disc sets."
    )

    @classmethod
    def _extra(cls, params: dict) -> str:
        return f" (mode {math.sqrt(params['k_link'] / params['m_link']) / (2.0 * math.pi):.3g} Hz)"

    @classmethod
    def adjust(cls, slots, substep_s):
        # the link's mode must be resolved by the explicit step: the mass at least k (h MIN_STEPS_PER_RAD)^2
        key = f"{cls.name}.m_link"
        if slots.get(f"{cls.name}.on") and key in slots:
            least = slots[f"{cls.name}.k_link"] * (MIN_STEPS_PER_RAD * substep_s) ** 2
            slots[key] = max(slots[key], least)


class LinkRodCrank(Link):
    """The rod-crank joint as a spring: the piston (mass m_link) and the crank are separate bodies."""

    name = "aug_link_rod_crank"
    title = "compliance with a mass in the rod-crank link"
    where = "the rod-crank link (the piston a mass on a spring to the crank)"
    constants = Link.constants + (
        Param("m_min", "kg", 0.5, (0.0, 1e3), "least piston mass of the two-body model (its m_link's lower bound)"),
    )

    @staticmethod
    def joint_force(gap, gap_rate, k_link, m_link, zeta_link):
        return k_link * gap + 2.0 * zeta_link * math.sqrt(k_link * m_link) * gap_rate

    @staticmethod
    def moving_mass(m_link):
        return m_link


class LinkMount(Link):
    """The actuator's body on a spring to the ground: the pressures push it back (-A p_load), the chambers see
    the piston's motion relative to it, and the sensor (in the cylinder) reads the piston relative to it."""

    name = "aug_link_mount"
    title = "compliance with a mass in the actuator's mount"
    where = "the actuator's mount (the cylinder's body a mass on a spring to the ground)"
    states = (("y_body", "m", 0.0), ("w_body", "m/s", 0.0))

    @staticmethod
    def state_rates(p_load, y_body, w_body, area, k_link, m_link, zeta_link):
        c = 2.0 * zeta_link * math.sqrt(k_link * m_link)
        return w_body, (-area * p_load - k_link * y_body - c * w_body) / m_link

    @staticmethod
    def chamber_flows(w_body, area):
        # the chambers change with the piston's motion relative to the body: v - w_body
        return area * w_body, -area * w_body

    @staticmethod
    def position_reading(x, y_body):
        return x - y_body


# -- a volume with a resistance in a hydraulic path ------------------------------------------------------------------

class Hose(Augmentation):
    """A line volume between the valve's port and a chamber, filled by the valve's land at the line's pressure and
    draining into the chamber through a laminar resistance: the chamber's inflow is (p_line - p_chamber) / R in
    place of the valve's, and p_line' = beta / V_line (q_valve(p_line) - (p_line - p_chamber) / R)."""

    form = "a hose"
    params = (
        Param("V_line", "cm^3", 10.0, (5.0, 3000.0),
              "line volume: oil between the valve's port and the resistance (assumed range: a short hose to a "
              "long one of 3 L; typical 0.3 to 4 m of 8 mm bore, 15 to 200 cm^3; default 10 cm^3, a short hose "
              "that does almost nothing: where a fit starts from no effect)", typical=(15.0, 200.0),
              si=1.0e-6, log_scale=True),
        Param("R_line", "bar/(L/min)", 0.1, (0.01, 20.0),
              "laminar resistance: 128 mu L / (pi d^4) of a hose, or a restrictor (assumed range; a 3 m, 6 mm "
              "hose at 32 cSt: about 0.5; default 0.1, nearly none)", typical=(0.1, 2.0), si=BAR_PER_LPM,
              log_scale=True),
    )
    main_param = "R_line"
    explanation = (
        "A hose between the valve and a chamber is a volume and a resistance: the valve meters against the "
        "line's pressure, the chamber fills through the line's laminar resistance R. At rest the line's pressure "
        "is the chamber's; moving, it leads it by R q, and the line's volume adds to the chamber's compliance. "
        "A resistance too small for the integrator's sub-step is raised to the least it resolves (the "
        "relaxation's time constant R / (beta (1/V_line + 1/V_chamber)) at least 0.6 sub-steps; below, only the "
        "line's volume acts)."
    )
    signature = (
        "a pressure residual on one side proportional to that side's flow (the line's drop R q), the valve's "
        "flow lower where the line's pressure is nearer the supply; a softer hydraulic spring on that side."
    )

    @classmethod
    def adjust(cls, slots, substep_s):
        key = f"{cls.name}.R_line"
        if slots.get(f"{cls.name}.on") and key in slots:
            # the relaxation's time constant R / (beta (1 / V_line + 1 / V_chamber)), the chamber at mid-stroke
            v_chamber = slots["area"] * slots["half_stroke"] + slots["dead_volume"]
            stiff = slots["beta"] * (1.0 / slots[f"{cls.name}.V_line"] + 1.0 / v_chamber)
            slots[key] = max(slots[key], MIN_STEPS_PER_TAU * substep_s * stiff)


class HoseA(Hose):
    """The hose at chamber A."""

    name = "aug_hose_a"
    title = "volume with a resistance in the line to chamber A (hose)"
    where = "the line from the valve to chamber A"
    states = (("p_line", "Pa", 0.5 * SUPPLY_PRESSURE),)

    @staticmethod
    def state_rates(qc, ps, pa, beta, rated_drop, p_line, V_line, R_line):
        d = ps - p_line if qc >= 0.0 else p_line  # the land metering into A (ehas_env.physics.baseline.land_flows)
        q_valve = qc * math.copysign(math.sqrt(abs(d) / (0.5 * rated_drop)), d)
        return beta / V_line * (q_valve - (p_line - pa) / R_line)

    @staticmethod
    def chamber_flows(q_a, pa, p_line, R_line):
        return (p_line - pa) / R_line - q_a, 0.0

    @staticmethod
    def port_pressures(pa, pb, p_line):
        return p_line, pb


class HoseB(Hose):
    """The hose at chamber B."""

    name = "aug_hose_b"
    title = "volume with a resistance in the line to chamber B (hose)"
    where = "the line from the valve to chamber B"
    states = (("p_line", "Pa", 0.5 * SUPPLY_PRESSURE),)

    @staticmethod
    def state_rates(qc, ps, pb, beta, rated_drop, p_line, V_line, R_line):
        d = p_line if qc >= 0.0 else ps - p_line  # the land metering into B (ehas_env.physics.baseline.land_flows)
        q_valve = -qc * math.copysign(math.sqrt(abs(d) / (0.5 * rated_drop)), d)
        return beta / V_line * (q_valve - (p_line - pb) / R_line)

    @staticmethod
    def chamber_flows(q_b, pb, p_line, R_line):
        return 0.0, (p_line - pb) / R_line - q_b

    @staticmethod
    def port_pressures(pa, pb, p_line):
        return pa, p_line


class HoseAB(Hose):
    """A hose in each line, alike (the usual pair of hoses from a valve manifold to the cylinder's ports): one volume
    and one resistance, in a form that stays integrable however small the hose.

    Each land meters against its line's pressure (the flow meter at the valve's port reads that flow,
    :meth:`port_pressures`), and the line drains into its chamber through R: V_line / beta p_line' = q_land -
    (p_line - p) / R.  A hose whose exchange with its chamber, R / (beta (1/V_line + 1/V_chamber)), the integrator
    does not resolve (R below ``R_exact``) is taken quasi-static instead: the land's flow q solves
    q = q_c sgn(d) sqrt(|d| / (dp_n / 2)) with d its drop at p_line = p + R q (a quadratic in sqrt(|d|), in closed
    form), the line's pressure follows p + R q within ``T_min`` (a sub-step), and the chamber receives q less what
    the line's volume stores, through a state that follows it within ``T_min`` so that the chamber's pressure never
    sees the stiff 1 / R -- the drop R q exact, the volume's compliance kept.  (The single-line hoses
    :class:`HoseA`, :class:`HoseB` raise such a resistance to the least resolved instead.)"""

    name = "aug_hose_ab"
    title = "volume with a resistance in each line, A and B (a pair of hoses)"
    where = "each line from the valve to its chamber"
    states = (("p_line_a", "Pa", 0.5 * SUPPLY_PRESSURE), ("p_line_b", "Pa", 0.5 * SUPPLY_PRESSURE),
              ("q_in_a", "m^3/s", 0.0), ("q_in_b", "m^3/s", 0.0))
    constants = (
        Param("T_min", "s", 1.0e-4, (1.0e-7, 1.0),
              "time constant of the quasi-static hose's states: the integrator's sub-step (times sqrt(V_line / "
              "V_chamber) where the line holds more oil than the chamber), set when the model is built"),
        Param("R_exact", "Pa s/m^3", 0.0, (0.0, 1.0e30),
              "least resistance the line's own balance is integrated with (below it, quasi-static): the "
              "relaxation R / (beta (1/V_line + 1/V_chamber)) at least 0.6 sub-steps, set when the model is built"),
    )

    @staticmethod
    def state_rates(qc, ps, pa, pb, beta, rated_drop, p_line_a, p_line_b, q_in_a, q_in_b, V_line, R_line, T_min,
                    R_exact):
        cap = V_line / beta
        if R_line >= R_exact:
            # a hose the sub-step resolves: the line's own balance, the lands metering at the lines' pressures
            # (ehas_env.physics.baseline.land_flows); the chamber's inflow (p_line - p) / R (chamber_flows)
            da = ps - p_line_a if qc >= 0.0 else p_line_a
            db = p_line_b if qc >= 0.0 else ps - p_line_b
            q_va = qc * math.copysign(math.sqrt(abs(da) / (0.5 * rated_drop)), da)
            q_vb = -qc * math.copysign(math.sqrt(abs(db) / (0.5 * rated_drop)), db)
            in_a, in_b = (p_line_a - pa) / R_line, (p_line_b - pb) / R_line
            return (q_va - in_a) / cap, (q_vb - in_b) / cap, -q_in_a / T_min, -q_in_b / T_min
        else:
            # quasi-static: |q| = 2 |d0| / (R + sqrt(R^2 + 4 |d0| / c2)) solves q^2 = c2 (d0 - R q), d0 the land's
            # drop at the chamber's pressure, c2 = qc^2 / (dp_n / 2); the line follows p + R q within T_min
            c2 = qc * qc / (0.5 * rated_drop)
            d0a = ps - pa if qc >= 0.0 else pa
            d0b = pb if qc >= 0.0 else ps - pb
            ma = mb = 0.0
            if c2 > 0.0:
                ma = math.copysign(2.0 * abs(d0a) / (R_line + math.sqrt(R_line * R_line + 4.0 * abs(d0a) / c2)), d0a)
                mb = math.copysign(2.0 * abs(d0b) / (R_line + math.sqrt(R_line * R_line + 4.0 * abs(d0b) / c2)), d0b)
            qa = ma if qc >= 0.0 else -ma
            qb = -mb if qc >= 0.0 else mb
            rate_a = (pa + R_line * qa - p_line_a) / T_min
            rate_b = (pb + R_line * qb - p_line_b) / T_min
            in_a, in_b = qa - cap * rate_a, qb - cap * rate_b
        return rate_a, rate_b, (in_a - q_in_a) / T_min, (in_b - q_in_b) / T_min

    @staticmethod
    def chamber_flows(q_a, q_b, pa, pb, p_line_a, p_line_b, q_in_a, q_in_b, R_line, R_exact):
        if R_line >= R_exact:
            return (p_line_a - pa) / R_line - q_a, (p_line_b - pb) / R_line - q_b
        return q_in_a - q_a, q_in_b - q_b

    @staticmethod
    def port_pressures(pa, pb, p_line_a, p_line_b):
        return p_line_a, p_line_b

    @classmethod
    def adjust(cls, slots, substep_s):
        # the states' least time constant: a sub-step, longer where the line's oil outweighs the chamber's (the
        # exchange of the two is then an oscillation of rate sqrt(V_line / V_chamber) / tau)
        if slots.get(f"{cls.name}.on"):
            v_chamber = slots["area"] * slots["half_stroke"] + slots["dead_volume"]
            v_line = slots[f"{cls.name}.V_line"]
            slots[f"{cls.name}.T_min"] = substep_s * max(1.0, math.sqrt(v_line / v_chamber))
            slots[f"{cls.name}.R_exact"] = (MIN_STEPS_PER_TAU * substep_s * slots["beta"]
                                            * (1.0 / v_line + 1.0 / v_chamber))


#: play in a joint: the library's effect (rod-crank joint), tried by the state stage with the others
PLAY = ("backlash",)


def augmentations() -> list[str]:
    """The names of the generic augmentations, one per kind and place, in the order the state stage tries them.

    Returns
    -------
    list of str
        Effect names (registered): the lags and the rate limit, the links, the hoses, then the play.
    """
    order = (LagCoil, SlewCoil, LagPositionSensor, LinkRodCrank, LinkMount, HoseAB, HoseA, HoseB)
    return [c.name for c in order] + list(PLAY)
