"""Generic state augmentations: one definition per kind of missing state, applied place by place (issue 33, item 2).

A rig always holds something no one listed; much of it is a *state* the baseline lacks.  Four kinds cover the
usual ones (Merritt ch. 5-6; Jelali & Kroll ch. 3), each one class here that holds the kind's parameters (unit,
bounds, doc), its explanation, residual signature and its words; the followers are generated at every signal place
from the place's description, the links and hoses have a subclass per place that holds only the terms that put the
kind's state there:

* **followers** in a signal path, each kind defined once and applied at every :class:`SignalPlace` the model has
  (:data:`SIGNAL_PLACES`: the current at the valve's coil, the position sensor's reading, and every sensed output's
  reading, :data:`ehas_env.physics.layout.SENSED`): a lag, a rate limit, a pure delay, a play
  (:mod:`ehas_env.physics.followers`); and **static blocks** at every sensor's reading (:data:`READING_PLACES`): an
  offset, a scale error, a saturation, a dead zone, a knee (:mod:`ehas_env.physics.statics`).  A new kind is one
  class; a new sensed output is a new place for every kind;
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
(:mod:`ehas_env.diagnosis.states`) does, place by place (:func:`augmentations`).

A follower at a place whose signal has a rate in the model keeps the error between what it passes on and what
comes (0 at rest, whatever the position or pressure a run starts from); at the coil it keeps the current itself
(0 mA at rest); a line's
pressure starts at the chambers' initial half supply pressure (:meth:`ehas_env.simulation.plant.Plant.initial_state`)
of the book's rig, and relaxes to its chamber's within a fraction of a millisecond on a rig whose supply differs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from ehas_env.physics.effects.base import Effect, Param
from ehas_env.physics.layout import SENSED
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
    #: (:func:`ehas_env.diagnosis.candidates.screen_candidate`): a state may add what that number took over
    screen_from_defaults: ClassVar[bool] = True
    #: the kind, in words ("a first-order lag")
    form: ClassVar[str] = ""
    #: the place, in words ("the position sensor's reading")
    where: ClassVar[str] = ""
    #: how the words show a parameter: {name: (factor from its unit, unit shown)}
    shown: ClassVar[dict] = {}
    #: the words between the kind and its main parameter's value ("a saturation at +-10.5 L/min")
    joins: ClassVar[str] = " of "

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
        return f"{cls.form}{cls.joins}{one(p[0])}{rest} in {cls.where}{cls._extra(params)}"

    @classmethod
    def _extra(cls, params: dict) -> str:
        return ""

    @classmethod
    def scan_hint(cls, peak: float, peak_rate: float) -> tuple:
        """Values of the main parameter the logged signal at the block's place points at, given its largest
        magnitude ``peak`` and its largest rate of change ``peak_rate`` over the runs (the place's SI unit, and
        per second): scanned with the fit's grid, whose steps are wider than the valley of a clip or a limit
        (none unless the kind says)."""
        return ()

    @classmethod
    def start_hint(cls, peak: float, peak_rate: float) -> dict:
        """Starts of the kind's other parameters the logged signal at its place points at ({name: value}, in their
        units; the signal's largest magnitude ``peak`` and rate ``peak_rate`` in the place's SI unit): where their
        typical middle would leave the main parameter's scan without effect (none unless the kind says)."""
        return {}


# -- the places a generated block is put at (the kinds: ehas_env.physics.followers, ehas_env.physics.statics) ------

@dataclass(frozen=True)
class SignalPlace:
    """A place of the model where a signal passes on (a chain of :data:`~ehas_env.physics.effects.base.PLACES`
    whose term gets the signal so far and returns what is passed on, and may read the effect's own states).

    Attributes
    ----------
    place : str
        The model's place (``coil_current``, ``position_reading``, ``<output>_reading``).
    short : str
        The place in an effect's name (``aug_<kind>_<short>``).
    value : str
        The argument the place's term gets (the signal so far).
    rate : str or None
        The state-rates quantity that is the signal's rate: a follower then keeps its error ``e = y - u`` (0 at
        rest wherever the run starts); None: the model has no rate for it, the follower keeps ``y`` itself,
        starting at ``rest``.
    unit : str
        The signal's unit inside the model (SI, the current in mA).
    span : float
        The signal's typical span on this rig, in ``unit`` (sets a rate limit's range).
    shown : tuple of (float, str)
        The factor from ``unit`` to the unit words show, and that unit.
    where : str
        The place in words ("chamber B's pressure reading").
    in_loop : bool
        Whether a follower there is a rival of what makes the loop late (the position the controller feeds back: a
        lag of it makes the loop late as a delay of its command does); a logged reading's follower is not.
    """

    place: str
    short: str
    value: str
    rate: str | None
    unit: str
    span: float
    shown: tuple
    where: str
    in_loop: bool = False
    signed: bool = True


def _reading_places() -> tuple:
    """A :class:`SignalPlace` per sensed output of the model (:data:`ehas_env.physics.layout.SENSED`); a pressure
    (Pa) is absolute in the model, never negative: its reading is not ``signed`` (no dead zone about its zero)."""
    shown = {"Pa": (1.0e-5, "bar"), "m^3/s": (60000.0, "L/min"), "N": (1.0e-3, "kN")}
    return tuple(SignalPlace(f"{out}_reading", f"{out}_reading", arg, f"{arg}_rate" if rate else None, unit, span,
                             shown.get(unit, (1.0, unit)), words, signed=unit != "Pa")
                 for out, (arg, unit, rate, words, span) in SENSED.items())


#: every sensed output's reading (the places of the static kinds, :class:`Static`)
READING_PLACES = _reading_places()


#: every place where a signal passes on: the valve's coil (the current the torque motor acts on, a chain without a
#: rate: its followers start at 0 mA, the current at rest), the position sensor's reading (its rate is the piston's
#: velocity), and every sensed output's reading the model has a rate of (the flow meter's reading has none: the
#: model's flow there is the land's plus the valve's side flows, which the state rates do not see)
SIGNAL_PLACES = (
    # the coil is in the loop too, but its lag as a rival of a command delay is the structural hypothesis
    # hyp_coil_lag (tried by the hypotheses stage): not twice
    SignalPlace("coil_current", "coil", "i", None, "mA", 10.0, (1.0, "mA"), "the valve's current path (command to coil)"),
    SignalPlace("position_reading", "position_sensor", "x", "v", "m", 0.05, (1.0e3, "mm"),
                "the position sensor's reading", in_loop=True),
) + tuple(p for p in READING_PLACES if p.rate)  # a reading's follower keeps its error: it needs the reading's rate




def _block_class(kind, place: SignalPlace, name: str, texts, body: dict) -> type:
    """The effect class ``name`` that puts ``kind`` (a :class:`Follower` or :class:`Static` kind) at ``place``: its
    terms the functions ``texts`` define, ``body`` its attributes of the kind's own (states, chain order, rivals)."""
    body = {"name": name, "title": f"{kind.kind_title} in {place.where}", "where": place.where,
            "params": kind.kind_params(place), "shown": kind.kind_shown(place), "signal_place": place,
            "__module__": kind.__module__, "__qualname__": f"{kind.__name__}At_{place.short}",
            "__doc__": f"{kind.kind_title} in {place.where} (generated by {kind.__name__}.at).", **body}
    for text in texts:
        body.update({k: staticmethod(v) for k, v in _compiled_source(f"{name}.{text[4:text.index('(')]}",
                                                                      text).items()})
    return type(kind)(body["__qualname__"], (kind,), body)


def _compiled_source(label: str, text: str) -> dict:
    """The functions defined by ``text``, their source findable (``inspect.getsource``) under ``label``: the
    compiled model copies a term's source text."""
    import linecache

    filename = f"<ehas_env.physics.augment: {label}>"
    linecache.cache[filename] = (len(text), None, text.splitlines(True), filename)
    namespace = {"math": math}
    exec(compile(text, filename, "exec"), namespace)
    return {k: v for k, v in namespace.items() if callable(v) and getattr(v, "__code__", None)
            and v.__code__.co_filename == filename}










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
    first = ["aug_lag_coil", "aug_slew_coil", "aug_lag_position_sensor"]  # the usual ones, tried first
    order = (LinkRodCrank, LinkMount, HoseAB, HoseA, HoseB)
    return (first + [c.name for c in order] + list(PLAY) + [n for n in _followers.followers() if n not in first]
            + _statics.reading_blocks())


# the kinds of block, each in its own module (they build on the places above): imported here so that importing
# this module -- which ehas_env.physics.effects does -- registers every generated block; as modules, not names,
# so that importing one of them first works too (it imports this module, which then finds it mid-import)
from ehas_env.physics import followers as _followers, statics as _statics  # noqa: E402


def __getattr__(name: str):
    """The kinds' names, reached from here as before they had modules of their own (``augment.Follower``,
    ``augment.followers``; the docs' kind of one's own imports ``Follower`` from here)."""
    for module in (_followers, _statics):
        if hasattr(module, name):
            return getattr(module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
