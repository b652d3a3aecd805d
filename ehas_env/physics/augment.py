"""Generic state augmentations: one definition per kind of missing state, applied place by place (issue 33, item 2).

A rig always holds something no one listed; much of it is a *state* the baseline lacks.  Four kinds cover the
usual ones (Merritt ch. 5-6; Jelali & Kroll ch. 3), each one class here that holds the kind's parameters (unit,
bounds, doc), its explanation, residual signature and its words; the followers are generated at every signal place
from the place's description, the links and hoses have a subclass per place that holds only the terms that put the
kind's state there:

* **followers** in a signal path, each kind defined once (:class:`Follower`: the signal passed on follows the
  one that comes by a law of their gap) and applied at every :class:`SignalPlace` the model has
  (:data:`SIGNAL_PLACES`: the current at the valve's coil, the position sensor's reading, and every sensed output's
  reading, :data:`ehas_env.physics.layout.SENSED`): a **lag** (:class:`Lag`, a first-order filter
  ``T y' = u - y``: a coil's inductance, an LVDT demodulator's filter, a pressure transducer's) and a **rate
  limit** (:class:`RateLimit`: an amplifier's voltage headroom, a conditioner's slew rate).  A new kind is one
  class with its law; a new sensed output is a new place for every kind (:func:`followers`);
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
pressure starts at its chamber's (``rests_at``: at rest the line's pressure is its chamber's, on any rig's supply;
:func:`ehas_env.simulation.plant.at_rest`).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import ClassVar

from ehas_env.physics.effects.augmentation import Augmentation, kind_at, term_methods
from ehas_env.physics.effects.augmentation import fmt_interval as _fmt
from ehas_env.physics.effects.base import Param
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


# -- a follower in a signal path: a kind defined once, applied at every signal place --------------------------------

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
    held : tuple of (str, str)
        Kinds (their ``stem``, static or follower) the model or the library holds here, each with what holds it.
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
    #: the kinds the model or the library already holds at this place, as (kind stem, what holds it): the
    #: products (:data:`STATICS`, :data:`FOLLOWERS`) leave them out, not to try one law twice under two names
    held: tuple = ()


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
#: velocity), and every sensed output's reading (the flow meter's has no rate in the balances: its followers keep
#: what they pass on, from 0 L/min at rest, the flow the model meters computed for them, ``q``)
SIGNAL_PLACES = (
    # the coil is in the loop too, but its lag as a rival of a command delay is the structural hypothesis
    # hyp_coil_lag (tried by the hypotheses stage): not twice
    # the current's offset is the library's null bias, its dead zone the valve's deadband, its scale the valve's
    # gain K (recalibrated in every fit)
    SignalPlace("coil_current", "coil", "i", None, "mA", 10.0, (1.0, "mA"), "the valve's current path (command to coil)",
                held=(("offset", "valve_null_bias"), ("dz", "valve_deadband"), ("gain", "the valve's gain K"),
                      ("delay", "transport_delay"))),
    # the reading's zero and scale are the library's structural hypotheses of the sensor
    SignalPlace("position_reading", "position_sensor", "x", "v", "m", 0.05, (1.0e3, "mm"),
                "the position sensor's reading", in_loop=True,
                held=(("offset", "hyp_position_offset"), ("gain", "hyp_position_shape"), ("bend", "hyp_position_shape"))),
) + READING_PLACES  # a reading's follower keeps its error where the reading has a rate, itself where not


class Follower(Augmentation):
    """A kind of state in a signal path: the signal passed on, ``y``, follows the signal that comes, ``u``, by a law
    of the gap ``d = u - y``: ``y' = law(d)``.  One class per kind holds its parameters, words and law (a Python
    expression in ``d`` and its parameters); :meth:`at` makes the effect that puts it at a :class:`SignalPlace`,
    and :func:`followers` the whole product.  Where the place has a rate for its signal, the state is the error
    ``e = y - u`` (``e' = law(-e) - u'``, 0 at rest wherever the run starts), else ``y`` itself from rest."""

    #: y' as a Python expression of the gap d = u - y and the kind's parameters and constants
    law: ClassVar[str] = ""
    #: y' where the place has a rate for its signal: a Python expression of the gap d, the signal's rate (written
    #: ``{rate}``) and the kind's parameters; "" (most kinds) is :attr:`law` there too
    rate_law: ClassVar[str] = ""
    #: the kind in an effect's name and in its state's name
    stem: ClassVar[str] = ""
    #: the kind's title, before "in <place>"
    kind_title: ClassVar[str] = ""
    #: the effects a follower of this kind in the loop may be mistaken for (its ``mistaken_for`` there)
    loop_rivals: ClassVar[tuple] = ()
    #: what is passed on is ``u + through * (y - u)``: 1 passes the follower's output ``y``; 2 passes ``2 y - u``,
    #: the all-pass a first-order Pade delay is (:class:`Delay`)
    through: ClassVar[float] = 1.0

    @classmethod
    def kind_params(cls, place: SignalPlace) -> tuple:
        """The kind's parameters at ``place`` (a rate limit's range scales with the place's span)."""
        return cls.params

    @classmethod
    def kind_shown(cls, place: SignalPlace) -> dict:
        """How the words show the kind's parameters at ``place``: {name: (factor from its unit, unit shown)}."""
        return dict(cls.shown)

    @classmethod
    def at(cls, place: SignalPlace) -> type:
        """The effect (a registered subclass) that puts this kind at ``place``.

        Parameters
        ----------
        place : SignalPlace

        Returns
        -------
        type
            The class ``aug_<stem>_<place.short>``; its terms are written as source (the compiled model copies a
            term's source text), so the effect is an effect like any other file's.
        """
        name = f"aug_{cls.stem}_{place.short}"
        args = ", ".join(p.name for p in cls.kind_params(place) + cls.constants)
        if place.rate:  # the error e = y - u: e' = law(-e) - u'
            state = f"e_{cls.stem}"
            law = cls.rate_law.format(rate=place.rate) if cls.rate_law else cls.law
            rates = (f"def state_rates({place.rate}, {state}, {args}):\n    d = -{state}\n"
                     f"    return {law} - {place.rate}\n")
            gain = "" if cls.through == 1.0 else f"{cls.through!r} * "
            passed = f"def {place.place}({place.value}, {state}):\n    return {place.value} + {gain}{state}\n"
        else:  # y itself, from rest
            state = f"{place.value}_{cls.stem}"
            rates = f"def state_rates({place.value}, {state}, {args}):\n    d = {place.value} - {state}\n    return {cls.law}\n"
            passed = (f"def {place.place}({state}):\n    return {state}\n" if cls.through == 1.0 else
                      f"def {place.place}({place.value}, {state}):\n"
                      f"    return {place.value} + {cls.through!r} * ({state} - {place.value})\n")
        body = {"states": ((state, place.unit, 0.0),)}
        if place.place == "position_reading":
            # after the sensor's static effects (an offset, a shape): the state acts on what the conditioner outputs
            body["chain_order"] = 100
        # a follower in the loop makes it late, as a delay of the command does: tried in place of one kept; at a
        # logged reading it moves that reading alone, which no delay of the command stands in for
        body["mistaken_for"] = cls.loop_rivals if place.in_loop else ()
        return _block_class(cls, place, name, (rates, passed), body)


def _block_class(kind, place: SignalPlace, name: str, texts, body: dict) -> type:
    """The effect class ``name`` that puts ``kind`` (a :class:`Follower` or :class:`Static` kind) at ``place``: its
    terms the functions ``texts`` define, ``body`` its attributes of the kind's own (states, chain order, rivals)."""
    return kind_at(kind, place.short, name, place.where, texts,
                   {"params": kind.kind_params(place), "shown": kind.kind_shown(place), "signal_place": place, **body})


class Lag(Follower):
    """A first-order lag ``T y' = u - y`` of a signal: what the model passes on is ``y`` instead of ``u``."""

    form = "a first-order lag"
    stem = "lag"
    kind_title = "first-order lag"
    law = "d / T"
    params = (
        Param("T", "ms", 2.0, (0.05, 50.0),
              "time constant: a filter's, a coil's inductance over its resistance, a demodulator's smoothing "
              "(assumed range: tenths of a ms to tens of ms; Merritt sec. 5.8, an LVDT conditioner's 1-5 ms)",
              typical=(0.5, 8.0), si=1.0e-3, log_scale=True),
    )
    main_param = "T"
    #: a lag in the loop makes it late, as a delay of the command does: the diagnosis fits it in place of a
    #: transport delay it keeps (the signals the lag does not touch tell them apart)
    loop_rivals = ("transport_delay",)
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


class RateLimit(Follower):
    """A rate limit in a signal path: the signal passed on cannot change faster than ``S``.

    Where the model has no rate for the signal (the coil's current, whose command steps every control period), the
    follower ``y' = S tanh((u - y) / (S T_ss))``: a first-order follower of time constant T_ss for small steps,
    never faster than S for large ones (tanh keeps the right-hand side smooth for the integrator).  At the coil: a
    servo amplifier drives the torque motor's coil through its inductance with a bounded voltage, so the current
    rises at most (V_max - R i) / L, about constant (Jelali & Kroll 2003, the servo amplifier; Merritt 1967, the
    torque motor).

    Where the model has the signal's rate ``u'`` (a reading: the piston's velocity, a chamber's pressure rate), a
    conditioner's slew-rate limit: ``y' = min(max(u' + (u - y) / T_ss, -S), S)``, the input's own rate while it is
    below S (the signal passed unchanged: an amplifier's small-signal bandwidth is far above anything these runs
    resolve) and S beyond, catching up at S and then within T_ss.  The tanh follower there would lag every reading
    by T_ss u' below the limit: 0.1 ms of 0.56 m/s is 56 um on the position reading, six times its noise (drawn
    case d20, a limit of 557 mm/s: its best fit left the fastest run's angle at 28x its noise variance, this one
    at 1.2x)."""

    form = "a rate limit"
    stem = "slew"
    kind_title = "rate limit"
    law = "S * math.tanh(d / (S * T_ss))"
    rate_law = "min(max({rate} + d / T_ss, -S), S)"
    constants = (
        Param("T_ss", "s", 1.0e-4, (1.0e-5, 1.0e-2),
              "small-signal time constant of the follower (assumed: a current-feedback amplifier's 1.6 kHz "
              "bandwidth, faster than anything the 1-3 Hz runs resolve)"),
    )
    main_param = "S"
    explanation = (
        "The signal follows its input, but no faster than the rate S (at the coil: what the amplifier's voltage "
        "can drive through the coil's inductance): a step or a fast reversal becomes a ramp."
    )
    signature = (
        "a residual at the signal's fast reversals, growing with the runs' frequency and amplitude; a small sine "
        "is passed unchanged (a lag fitted to it comes out longer on the fast, large runs)."
    )

    @classmethod
    def kind_params(cls, place: SignalPlace) -> tuple:
        # from 0.05 to 10^4 spans a second (the coil: 0.5 mA/s to 100 mA/ms, typically 5 mA/s to 20 mA/ms; a span
        # is the sensor's range, which the rig's signals may fill a small part of: the load's 50 kN against a few
        # kN, whose rate limit of 10 kN/s is 0.2 spans a second)
        unit = f"{place.unit}/s"
        return (Param("S", unit, 200.0 * place.span, (0.05 * place.span, 1.0e4 * place.span),
                      f"largest rate of change of the signal, {unit} (assumed range: 0.05 to 10^4 times the signal's "
                      f"span of {place.span:g} {place.unit} a second; at the coil the amplifier's voltage headroom "
                      "over the coil's inductance: a 10 mA coil of 1 H on 10 V headroom, 10 mA/ms)",
                      typical=(0.5 * place.span, 2000.0 * place.span), log_scale=True),)

    @classmethod
    def scan_hint(cls, peak: float, peak_rate: float) -> tuple:
        # a rate-limited signal never changes faster than S: its largest rate is S (a limit just below the runs'
        # fastest rate acts on their peaks alone, a valley far narrower than the scan's steps)
        return (peak_rate,)

    @classmethod
    def kind_shown(cls, place: SignalPlace) -> dict:
        if place.unit == "mA":  # a coil's current: mA/ms, as amplifiers are specified
            return {"S": (place.shown[0] * 1.0e-3, f"{place.shown[1]}/ms")}
        return {"S": (place.shown[0], f"{place.shown[1]}/s")}


class Delay(Follower):
    """A pure delay of a signal (a converter's or a digital filter's latency, a transducer's transport time): what
    the model passes on is ``u(t - tau)``, taken as the first-order Pade all-pass ``(1 - s tau/2) / (1 + s tau/2)``:
    a lag ``y`` of time constant ``tau / 2`` and ``2 y - u`` passed on.  Gain 1 at every frequency, phase
    ``-2 atan(w tau / 2)``: within 1 % of the delay's ``-w tau`` while ``w tau < 0.35`` (a 3 Hz run's tenth harmonic
    under a 2 ms delay).  At the command the library's ``transport_delay`` is the delay."""

    form = "a pure delay"
    stem = "delay"
    kind_title = "pure delay"
    law = "d / (0.5 * tau)"
    through = 2.0
    params = (
        Param("tau", "ms", 1.0, (0.1, 30.0),
              "the delay: a converter's or filter's latency, a transducer's transport time (assumed range: a tenth "
              "of a ms -- its lag tau/2 then the lag's shortest, what the integrator's sub-step holds -- to tens of "
              "ms; Jelali & Kroll 2003, transport delays of digital drives and transducers)",
              typical=(0.2, 5.0), si=1.0e-3, log_scale=True),
    )
    main_param = "tau"
    #: a delay of the position fed back makes the loop late as a delay of the command does
    loop_rivals = ("transport_delay",)
    explanation = ("A signal arrives tau late: the output is the input's sine with gain 1 and a phase lag w tau "
                   "growing in proportion to frequency (no corner, unlike a lag).")
    signature = ("a residual in quadrature with the signal, proportional to frequency and to the signal's rate at "
                 "every harmonic alike; a lag fitted to it comes out shorter on the fast runs' harmonics.")


class Play(Follower):
    """Play (backlash, hysteresis) in a signal path: what is passed on stays put until the signal that comes has
    moved ``b`` past it, then follows it at that distance -- the output of a play operator of half width ``b``
    (Tao & Kokotovic 1996, backlash; at the coil, the torque motor's magnetic hysteresis, a few % of rated current
    in servo-valve data sheets; at a reading, a linkage's or a gauge's mechanical play).

    The follower ``y' = (d - clip(d, -b, b)) / T_p``: still while the gap ``d = u - y`` is within ``+-b``, closing
    what exceeds it with the time constant ``T_p``, far faster than the runs resolve."""

    form = "a play"
    joins = " of +-"
    stem = "play"
    kind_title = "play (backlash)"
    law = "(d - min(max(d, -b), b)) / T_p"
    constants = (
        Param("T_p", "s", 1.0e-4, (1.0e-5, 1.0e-2),
              "time constant with which the output closes the gap beyond the play (assumed: as the rate limit's "
              "small-signal constant, faster than anything the 1-3 Hz runs resolve)"),
    )
    main_param = "b"
    explanation = ("The output stays where it is until the input has moved the play's half width b past it, then "
                   "follows at that distance: at every reversal the output holds while the input crosses 2 b.")
    signature = ("a residual of size up to b right after every reversal of the signal, flat while the output "
                 "holds; the same on every run (not growing with frequency as a lag's does).")

    @classmethod
    def kind_params(cls, place: SignalPlace) -> tuple:
        # from 1e-4 span (below any resolution: no effect) to 0.2 span
        return (Param("b", place.unit, 1.0e-4 * place.span, (1.0e-4 * place.span, 0.2 * place.span),
                      f"the play's half width, {place.unit} (assumed range: 1e-4 to 0.2 times the signal's span of "
                      f"{place.span:g} {place.unit}; the default, 1e-4 span, is below any sensor's resolution: no "
                      "effect)", typical=(0.002 * place.span, 0.05 * place.span), log_scale=True),)

    @classmethod
    def kind_shown(cls, place: SignalPlace) -> dict:
        return {"b": place.shown}


#: the follower kinds, each applied at every signal place but where the model or the library holds that kind
FOLLOWER_KINDS = (Lag, RateLimit, Delay, Play)
#: the product, generated once (registered as effects when this module is imported)
FOLLOWERS = tuple(kind.at(place) for kind in FOLLOWER_KINDS for place in SIGNAL_PLACES
                  if kind.stem not in dict(place.held))


# -- a static block at a sensor's reading: a kind defined once, applied at every reading -----------------------------

class Static(Augmentation):
    """A kind of static block in a signal path: what is passed on (what a sensor reports, the current the coil
    gets) is ``expr`` of the signal ``u`` and the kind's parameters (no state).  :meth:`at` puts it at a signal
    place (:data:`SIGNAL_PLACES`: every sensed output's reading, the position sensor's reading, the coil's current);
    the kinds a place says the model or the library holds there (``SignalPlace.held``: the coil's null bias and
    deadband, the position sensor's zero and scale) are left out of the product."""

    #: what the sensor reports, a Python expression of the output ``u`` and the kind's parameters
    expr: ClassVar[str] = ""
    stem: ClassVar[str] = ""
    kind_title: ClassVar[str] = ""
    screen_from_defaults = False  # no state: nothing a re-opened beta or K could have taken over

    @classmethod
    def kind_params(cls, place: SignalPlace) -> tuple:
        """The kind's parameters at ``place``."""
        return cls.params

    @classmethod
    def kind_shown(cls, place: SignalPlace) -> dict:
        """How the words show the kind's parameters at ``place``."""
        return dict(cls.shown)

    @classmethod
    def fits(cls, place: SignalPlace) -> bool:
        """Whether the kind means something at ``place`` (every reading, unless the kind says otherwise)."""
        return True

    @classmethod
    def at(cls, place: SignalPlace) -> type:
        """The effect ``aug_<stem>_<place.short>`` that puts this kind at the reading ``place``."""
        name = f"aug_{cls.stem}_{place.short}"
        args = ", ".join(p.name for p in cls.kind_params(place))
        text = (f"def {place.place}({place.value}, {args}):\n    u = {place.value}\n    return {cls.expr_at(place)}\n")
        return _block_class(cls, place, name, (text,), {})

    @classmethod
    def expr_at(cls, place: SignalPlace) -> str:
        """What is passed on at ``place``, a Python expression of ``u`` and the kind's parameters (``expr``, unless
        the kind writes the place's numbers into it)."""
        return cls.expr


class Offset(Static):
    """An offset of a sensor's reading (a transducer's zero that drifted, a wrong tare)."""

    form = "an offset"
    stem = "offset"
    kind_title = "offset"
    expr = "u + c"
    main_param = "c"
    explanation = "The sensor reports the quantity plus a constant c: its zero is off."
    signature = "a constant residual on that reading alone, the same in every run and at every instant."

    @classmethod
    def kind_params(cls, place: SignalPlace) -> tuple:
        return (Param("c", place.unit, 0.0, (-0.1 * place.span, 0.1 * place.span),
                      f"the reading's offset, {place.unit} (assumed range: +-10 % of the signal's span of "
                      f"{place.span:g} {place.unit})", typical=(0.003 * place.span, 0.03 * place.span)),)

    @classmethod
    def kind_shown(cls, place: SignalPlace) -> dict:
        return {"c": place.shown}


class Gain(Static):
    """A scale error of a sensor's reading (a transducer's calibration off)."""

    form = "a scale error"
    stem = "gain"
    kind_title = "scale error"
    expr = "u * (1.0 + g)"
    main_param = "g"
    shown = {"g": (100.0, "%")}
    params = (Param("g", "-", 0.0, (-0.2, 0.2), "the reading's scale error, a share (assumed range: +-20 %)",
                    typical=(0.005, 0.05)),)
    explanation = "The sensor reports the quantity times (1 + g): its calibration is off."
    signature = "a residual on that reading alone, proportional to the reading itself."


class Bend(Static):
    """A reading (or a signal) that bends smoothly away from a straight line: an odd cubic term, ``b`` of the
    place's span at one span either way (a transducer's nonlinearity, given as a share of its span; the polynomial
    output block of a Hammerstein-Wiener model, its lowest odd term beyond the linear one)."""

    form = "a cubic bend"
    stem = "bend"
    kind_title = "cubic bend"
    expr = "u + b * s * (u / s) ** 3"
    main_param = "b"
    shown = {"b": (100.0, "% of the span")}
    params = (Param("b", "-", 0.0, (-0.3, 0.3),
                    "the departure from a straight line at one span either way, a share of the span (assumed range: "
                    "+-30 %; 0, the default, is no bend)", typical=(0.005, 0.05)),)
    explanation = ("What is passed on is u + b s (u / s)^3 (s: the signal's span on this rig): straight near zero, "
                   "bending by b of the span at one span either way.")
    signature = ("a residual on that reading alone (or, in the loop, on everything the loop moves) that grows with "
                 "the cube of the signal: none on the small runs, largest at the large runs' peaks, the same sign "
                 "as the signal.")

    @classmethod
    def expr_at(cls, place: SignalPlace) -> str:
        return re.sub(r"\bs\b", repr(float(place.span)), cls.expr)  # the span written in: one formula

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """E.g. "a cubic bend of 2.5 [2.4, 2.6] % of the span at +-25 L/min in the flow meter's reading (line A)"."""
        ci = ci or {}
        place = cls.signal_place
        f, unit = place.shown
        return (f"{cls.form} of {_fmt(params['b'], ci.get('b'), 100.0)} % of the span at +-{place.span * f:.3g} "
                f"{unit} in {cls.where}")


class Saturation(Static):
    """A reading that saturates: the sensor (its range, its amplifier, its converter) reports at most ``L`` either
    way (Jelali & Kroll 2003: sensor and amplifier ranges)."""

    form = "a saturation"
    joins = " at +-"
    stem = "sat"
    kind_title = "saturation"
    expr = "min(max(u, -L), L)"
    main_param = "L"
    explanation = ("The sensor reports the quantity up to L either way and L beyond it: its range, its amplifier's "
                   "or its converter's, ends inside what the rig does.")
    signature = ("a residual on that reading alone, zero while the reading is inside +-L and growing with the "
                 "quantity beyond it: flat tops on the large, fast runs, none on the small ones.")

    @classmethod
    def kind_params(cls, place: SignalPlace) -> tuple:
        # from a thousandth of the span to five spans (never reached: no effect); the span is the place's on the book's
        # rig, and a rig that uses a small part of it (rig C's loads peak near 1 kN of a 50 kN span) saturates where
        # its amplifier or converter is set for less: the fit's range (the typical one widened 4x) reaches down there
        return (Param("L", place.unit, 5.0 * place.span, (0.001 * place.span, 5.0 * place.span),
                      f"the largest value the reading reports either way, {place.unit} (assumed range: 0.001 to 5 "
                      f"times the signal's span of {place.span:g} {place.unit}; the default, 5 spans, is never "
                      "reached: no effect)", typical=(0.005 * place.span, 2.0 * place.span), log_scale=True),)

    @classmethod
    def kind_shown(cls, place: SignalPlace) -> dict:
        return {"L": place.shown}

    @classmethod
    def scan_hint(cls, peak: float, peak_rate: float) -> tuple:
        # a saturated reading never reports more than L: its largest magnitude is L (the valley of the clip level
        # is as narrow as the stretch the clip cuts off, narrower than the scan's steps)
        return (peak,)


class DeadZone(Static):
    """A reading with a dead zone about its zero: the sensor reports nothing until the quantity passes ``d`` either
    way, then the quantity less ``d`` (a turbine meter that does not turn below its threshold; a load cell's
    mounting play taken up by a preload; Jelali & Kroll 2003: dead zones of drives and sensors)."""

    form = "a dead zone"
    joins = " of +-"
    stem = "dz"
    kind_title = "dead zone"
    expr = "u - min(max(u, -d), d)"
    main_param = "d"
    explanation = ("The sensor reports zero while the quantity is within +-d and the quantity less d beyond it: "
                   "its reading starts late at every reversal.")
    signature = ("a residual on that reading alone at every zero crossing of the quantity, of size d, the same on "
                 "every run; none where the quantity stays far from zero.")

    @classmethod
    def fits(cls, place: SignalPlace) -> bool:
        return place.signed  # an absolute pressure is never near a zero a dead zone acts about

    @classmethod
    def kind_params(cls, place: SignalPlace) -> tuple:
        return (Param("d", place.unit, 1.0e-4 * place.span, (1.0e-4 * place.span, 0.2 * place.span),
                      f"the dead zone's half width, {place.unit} (assumed range: 1e-4 to 0.2 times the signal's span "
                      f"of {place.span:g} {place.unit}; the default, 1e-4 span, is below any sensor's resolution)",
                      typical=(0.005 * place.span, 0.05 * place.span), log_scale=True),)

    @classmethod
    def kind_shown(cls, place: SignalPlace) -> dict:
        return {"d": place.shown}


class Knee(Static):
    """A reading whose slope changes beyond a knee: the sensor reports the quantity as it is within ``+-k`` and with
    its slope changed by the share ``g`` beyond (a transducer's characteristic that bends at the end of its linear
    range, a load cell's mounting that stiffens or gives beyond a preload; piecewise-linear, the simplest of
    MATLAB's nonlinearity estimators for a Hammerstein-Wiener output block)."""

    form = "a slope change"
    stem = "knee"
    kind_title = "slope change beyond a knee"
    expr = "u + g * (u - min(max(u, -k), k))"
    main_param = "k"
    shown = {"g": (100.0, "%")}
    explanation = ("The sensor reports the quantity within +-k as it is, and beyond it with the slope 1 + g: a "
                   "characteristic that bends at k.")
    signature = ("a residual on that reading alone, zero while the quantity is within +-k and growing in "
                 "proportion to how far beyond it is: on the large runs' peaks, none on the small runs.")

    @classmethod
    def fits(cls, place: SignalPlace) -> bool:
        return place.signed  # a knee either way about zero: an absolute pressure has no zero it bends about

    @classmethod
    def kind_params(cls, place: SignalPlace) -> tuple:
        return (Param("g", "-", 0.0, (-0.9, 3.0),
                      "the change of slope beyond the knee, a share of the slope within (assumed range: -90 % "
                      "to +300 %; 0, the default, is no knee)", typical=(0.1, 0.6)),
                Param("k", place.unit, 0.3 * place.span, (0.001 * place.span, 3.0 * place.span),
                      f"knee: the magnitude beyond which the slope changes, {place.unit} (assumed range: 0.001 to 3 "
                      f"times the signal's span of {place.span:g} {place.unit}: a sensor's span is its range, which "
                      "the rig may fill a small part of)",
                      typical=(0.005 * place.span, 0.6 * place.span), log_scale=True))

    @classmethod
    def kind_shown(cls, place: SignalPlace) -> dict:
        return {"g": (100.0, "%"), "k": place.shown}

    @classmethod
    def scan_hint(cls, peak: float, peak_rate: float) -> tuple:
        # knees within the reading's logged range (the grid's steps over a sensor's span, a factor 3.6 apart, may
        # put one point at most where the rig's readings reach); k is in the place's unit
        return (0.25 * peak, 0.5 * peak, 0.75 * peak)

    @classmethod
    def start_hint(cls, peak: float, peak_rate: float) -> dict:
        # from no slope change (when the typical one's sign is wrong), the knee inside the logged range
        return {"k": 0.5 * peak}

    @classmethod
    def in_words(cls, params: dict, ci: dict | None = None) -> str:
        """E.g. "a slope change of 50.2 [45, 55] % beyond +-0.675 [0.65, 0.7] kN in the load reading"."""
        ci = ci or {}
        (gs, gu), (ks, ku) = cls.shown["g"], cls.shown["k"]
        return (f"{cls.form} of {_fmt(params['g'], ci.get('g'), gs)} {gu} beyond +-{_fmt(params['k'], ci.get('k'), ks)} "
                f"{ku} in {cls.where}")


#: the static kinds, each applied at every signal place it fits and the place does not hold already
STATIC_KINDS = (Offset, Gain, Saturation, DeadZone, Knee, Bend)
STATICS = tuple(kind.at(place) for kind in STATIC_KINDS for place in SIGNAL_PLACES
                if kind.fits(place) and kind.stem not in dict(place.held))


def followers() -> list[str]:
    """The names of every follower kind at every signal place: :data:`FOLLOWER_KINDS` x :data:`SIGNAL_PLACES`, and
    the followers a user's effect file made with :meth:`Follower.at` (a kind of one's own joins the state stage
    as the built-in ones do).

    Returns
    -------
    list of str
        E.g. ``aug_lag_coil``, ``aug_lag_position_sensor``, ``aug_lag_pb_reading``, ``aug_slew_coil``, in the order
        they registered.

    Examples
    --------
    >>> names = followers()
    >>> "aug_lag_pb_reading" in names and "aug_slew_position_sensor" in names
    True
    >>> from ehas_env.physics.effects import get_effect
    >>> get_effect("aug_lag_pb_reading").in_words({"T": 2.1})
    "a first-order lag of 2.1 ms in chamber B's pressure reading (corner 75.8 Hz)"
    """
    from ehas_env.physics.effects.base import REGISTRY

    return [n for n, c in REGISTRY.items()
            if isinstance(getattr(c, "signal_place", None), SignalPlace) and issubclass(c, Follower)]


def reading_blocks() -> list[str]:
    """The names of every static kind at every signal place it fits (:data:`STATIC_KINDS` x :data:`SIGNAL_PLACES`:
    every sensor's reading, the position sensor's, the coil's current path; less the kinds a place holds already,
    ``SignalPlace.held``), and those a user's file made with :meth:`Static.at`.

    Returns
    -------
    list of str
        E.g. ``aug_offset_pb_reading``, ``aug_gain_flow_a_reading``.

    Examples
    --------
    >>> from ehas_env.physics.effects import get_effect
    >>> get_effect("aug_offset_pb_reading").in_words({"c": 1.5e5})
    "an offset of 1.5 bar in chamber B's pressure reading"
    """
    from ehas_env.physics.effects.base import REGISTRY

    return [n for n, c in REGISTRY.items()
            if isinstance(getattr(c, "signal_place", None), SignalPlace) and issubclass(c, Static)]


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
              si=1.0e-6, log_scale=True,
              limit=("lower", "the line's resistance alone: its oil too little for the logs to resolve")),
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
        "A hose whose exchange with its chamber the integrator's sub-step does not resolve (R / (beta (1/V_line + "
        "1/V_chamber)) under 0.6 sub-steps) is taken quasi-static: the land's flow passes the line at once but for "
        "what its oil takes as its pressure moves, the drop R q and the compliance exact (a short line of little "
        "resistance does little, as it should)."
    )
    signature = (
        "a pressure residual on one side proportional to that side's flow (the line's drop R q), the valve's "
        "flow lower where the line's pressure is nearer the supply; a softer hydraulic spring on that side."
    )
    constants = (
        Param("T_min", "s", 1.0e-4, (1.0e-7, 1.0),
              "time constant of the quasi-static hose's states (its line's pressure, what passes R): the "
              "integrator's sub-step, set when the model is built"),
        Param("R_exact", "Pa s/m^3", 0.0, (0.0, 1.0e30),
              "least resistance the line's own balance is integrated with (below it, quasi-static): the "
              "relaxation R / (beta (1/V_line + 1/V_chamber)) at least 0.6 sub-steps, set when the model is built"),
    )

    @classmethod
    def adjust(cls, slots, substep_s):
        # the quasi-static states follow algebraic targets (no exchange of two volumes through a stiff 1 / R is
        # integrated there): a sub-step is their least time constant
        if slots.get(f"{cls.name}.on"):
            v_chamber = slots["area"] * slots["half_stroke"] + slots["dead_volume"]
            v_line = slots[f"{cls.name}.V_line"]
            slots[f"{cls.name}.T_min"] = substep_s
            slots[f"{cls.name}.R_exact"] = (MIN_STEPS_PER_TAU * substep_s * slots["beta"]
                                            * (1.0 / v_line + 1.0 / v_chamber))


#: each line's words in a hose's source: its chamber's pressure, when its land meters from the supply, the sign of
#: its flow against the valve's no-load flow q_c (:func:`ehas_env.physics.baseline.land_flows`), the sign of its
#: chamber's volume change with x and of the flow the piston displaces out of it (:func:`ehas_env.physics.baseline.
#: chamber_rates`: V = v0 + A x, out A v on side A; V = v0 - A x, out -A v on side B)
_LINE = {"a": ("pa", "qc >= 0.0", "", "+"), "b": ("pb", "qc < 0.0", "-", "-")}


def _quasi_land_texts(x: str) -> list[str]:
    """The land of the quasi-static line ``x`` (``"a"`` or ``"b"``) in a hose's source: its flow q through the
    orifice against the line's pressure p + R (q - S), S (the state ``q_in``) what the line's oil takes: q = q_c sgn
    sqrt(|drop| / (dp_n / 2)) with drop = d0 + s R S - R |q| (a quadratic in sqrt, in closed form; s = +1
    metering in from the supply, -1 out to the tank)."""
    p, supplied, sign, _ = _LINE[x]
    return [f"        d0{x} = (ps - {p} if {supplied} else {p}) + (1.0 if {supplied} else -1.0) * R_line * q_in_{x}",
            f"        m{x} = 0.0 if c2 <= 0.0 else math.copysign(2.0 * abs(d0{x}) / (R_line + math.sqrt(R_line * "
            f"R_line + 4.0 * abs(d0{x}) / c2)), d0{x})",
            f"        q{x} = {sign}(m{x} if qc >= 0.0 else -m{x})"]


def _hose_texts(sides: str) -> list[str]:
    """The source of the terms of a hose in each line of ``sides`` (``"a"``, ``"b"`` or ``"ab"``): one law, written
    once for any set of lines (the compiled model copies a term's text).

    Each land meters against its line's pressure, and the line drains into its chamber through R: V_line / beta
    p_line' = q_land - (p_line - p) / R.  A hose whose exchange with its chamber, R / (beta (1/V_line +
    1/V_chamber)), the integrator does not resolve (R below ``R_exact``) is taken quasi-static instead: the land's
    flow q passes the line at once (:func:`_quasi_land_texts`) but for S, what the line's oil takes as its pressure
    moves, cap (p' + dl') -- the chamber's pressure rate and the drop dl = p_line - p, which follows R (q - S)
    within ``T_min`` (a sub-step).  S (the state ``q_in``) follows that within a time the integrator resolves,
    0.7 T_min (1 + (V_line / V_chamber) T_min / (T_min + R cap)): the chamber's rate reads S, and S the chamber's
    rate.  The drop R q and the line's compliance are kept, and the chamber's inflow is never lagged.  (A quasi-static line that lagged
    the chamber's whole inflow by a sub-step, twice, missed a small rig whose hose held more oil than its chamber
    by 0.7 bar rms where the resolved integration leaves the noise: held-out d06 at the truth's values.)
    """
    lines = [(x, *_LINE[x]) for x in sides]
    states = [f"p_line_{x}" for x in sides] + [f"q_in_{x}" for x in sides]
    exact, quasi = [], []
    for x, p, supplied, sign, vol in lines:
        exact += [f"        d{x} = ps - p_line_{x} if {supplied} else p_line_{x}",
                  f"        q_v{x} = {sign}qc * math.copysign(math.sqrt(abs(d{x}) / (0.5 * rated_drop)), d{x})",
                  f"        in_{x} = (p_line_{x} - {p}) / R_line"]
        quasi += _quasi_land_texts(x) + [
            f"        dl_rate{x} = (R_line * (q{x} - q_in_{x}) - (p_line_{x} - {p})) / T_min",
            # what the oil takes, S = cap (p' + dl') with dl' = (R (q - S) - dl) / T_min: solved for S
            f"        s_t{x} = cap * (p{x}_rate * T_min + R_line * q{x} - (p_line_{x} - {p})) / (T_min + R_line * cap)",
            # S's own relaxation: 1 + (cap / C_chamber) T_min / (T_min + R cap) over t_s, 1.4 a sub-step (RK4 holds 2.8;
            # at 2 a line of 400 cm^3 on the book's rig still held, at 2.9 it blew up)
            f"        t_s{x} = 0.7 * T_min * (1.0 + V_line / (area * half_stroke + dead_volume {vol} area * x) * T_min / "
            "(T_min + R_line * cap))"]
    c2 = "        c2 = qc * qc / (0.5 * rated_drop)"
    rates = ", ".join
    state_rates = "\n".join(
        [f"def state_rates(qc, ps, pa, pb, x, {', '.join(f'p{x}_rate' for x in sides)}, beta, rated_drop, area, "
         f"half_stroke, dead_volume, {', '.join(states)}, V_line, R_line, T_min, R_exact):",
         "    cap = V_line / beta",
         "    if R_line >= R_exact:"] + exact +
        [f"        return {rates([f'(q_v{x} - in_{x}) / cap' for x in sides] + [f'-q_in_{x} / T_min' for x in sides])}",
         "    else:", c2] + quasi +
        [f"        return {rates([f'p{x}_rate + dl_rate{x}' for x, *_ in lines] + [f'(s_t{x} - q_in_{x}) / t_s{x}' for x in sides])}"])
    exact_flows = {x: f"(p_line_{x} - {p}) / R_line - q_{x}" for x, p, *_ in lines}
    chamber_flows = "\n".join(
        [f"def chamber_flows(q_a, q_b, pa, pb, qc, ps, rated_drop, {', '.join(states)}, R_line, R_exact):",
         "    if R_line >= R_exact:",
         f"        return {exact_flows.get('a', '0.0')}, {exact_flows.get('b', '0.0')}",
         "    else:", c2] + [t for x in sides for t in _quasi_land_texts(x)] +
        [f"        return {'qa - q_in_a - q_a' if 'a' in sides else '0.0'}, "
         f"{'qb - q_in_b - q_b' if 'b' in sides else '0.0'}"])
    port_pressures = "\n".join(
        [f"def port_pressures(pa, pb, {', '.join(f'p_line_{x}' for x in sides)}):",
         f"    return {'p_line_a' if 'a' in sides else 'pa'}, {'p_line_b' if 'b' in sides else 'pb'}"])
    return [t + "\n" for t in (state_rates, chamber_flows, port_pressures)]


def _hose(sides: str, name: str, title: str, where: str, doc: str) -> type:
    """The hose effect ``name`` in the lines ``sides`` (:func:`_hose_texts`)."""
    body = {"name": name, "title": title, "where": where, "__doc__": doc, "__module__": __name__,
            "__qualname__": f"Hose{sides.upper()}",
            "states": tuple((f"p_line_{x}", "Pa", 0.5 * SUPPLY_PRESSURE) for x in sides)
            + tuple((f"q_in_{x}", "m^3/s", 0.0) for x in sides), "rests_at": {f"p_line_{x}": f"p{x}" for x in sides},
            **term_methods(name, _hose_texts(sides))}
    return type(Hose)(body["__qualname__"], (Hose,), body)


HoseA = _hose("a", "aug_hose_a", "volume with a resistance in the line to chamber A (hose)",
              "the line from the valve to chamber A", "The hose at chamber A.")
HoseB = _hose("b", "aug_hose_b", "volume with a resistance in the line to chamber B (hose)",
              "the line from the valve to chamber B", "The hose at chamber B.")
HoseAB = _hose("ab", "aug_hose_ab", "volume with a resistance in each line, A and B (a pair of hoses)",
               "each line from the valve to its chamber",
               "A hose in each line, alike (the usual pair of hoses from a valve manifold to the cylinder's ports): "
               "one volume and one resistance.")


class PortLine(Augmentation):
    """A line volume behind a laminar resistance at one of the valve's boundary ports, the supply's or the
    return's: the lands meter against the line's pressure at the port, which the line's flow through R pulls away
    from the far end's (the supply's gauge, the tank), and the line's oil V / beta lags it.  Its state is that
    drop, ``dp_line`` (0 at rest): C dp' = q - dp / R with q the flow the lands send through the line (the
    supply's draw, or what the return lands pass: the supply's draw less what flows out of ports A and B).

    The drop's relaxation is as fast as the land's own conductance g = |q| / (2 |its drop|) makes it
    (C / (1 / R + g)); where that is shorter than the integrator's sub-step (``T_min``) the line's compliance is
    taken as T_min (1 / R + g): the drop R q exact, its lag one sub-step, far below what a log at 1 kHz resolves.
    The valve's flow bench has its own regulated supply and return: a line's drop keeps its rest there."""

    form = "a line volume"
    params = Hose.params
    main_param = "R_line"
    constants = (Param("T_min", "s", 1.0e-4, (1.0e-7, 1.0),
                       "the least relaxation of the line's drop: the integrator's sub-step, set when the model is "
                       "built"),)
    states = (("dp_line", "Pa", 0.0),)
    explanation = (
        "A line between the supply's gauge and the valve's pressure port (or between its tank port and the tank) "
        "is a volume behind a resistance: the flow it carries drops R q across it, so the lands meter from less "
        "than the gauge reads (or into more than the tank's pressure), and its oil lags that drop. Nothing "
        "changes at rest; the more the valve passes, the more it loses."
    )
    #: the port (``"supply"`` or ``"return"``), the words of the line's far end
    port: ClassVar[str] = ""
    signature = (
        "the valve's flow lower where it is large (the line's drop R q taken from the land's), the supply's "
        "gauge flat while the chambers see less than it; a softer supply or return at the valve's ports."
    )

    @classmethod
    def adjust(cls, slots, substep_s):
        if slots.get(f"{cls.name}.on"):
            slots[f"{cls.name}.T_min"] = substep_s


#: each port's line in a line volume's source: how its drop changes the lands' pressures, the flow through it (the
#: supply's draw; what the return lands pass, the supply's draw less what leaves through ports A and B), the
#: land whose drop it shares (the one from the supply, or to the tank, as the valve's opening qc sets), and the
#: quantities that reads
_PORT = {"supply": ("p_sup - dp_line, p_ret", "q_supply", "ps - dp_line - (pa if qc >= 0.0 else pb)",
                    "qc, pa, pb, ps, q_supply"),
         "return": ("p_sup, p_ret + dp_line", "q_supply - q_a - q_b", "(pb if qc >= 0.0 else pa) - dp_line",
                    "qc, pa, pb, q_a, q_b, q_supply")}


def _port_line_texts(port: str) -> list[str]:
    """The source of a line volume's terms at ``port``: one law for either port, C dp' = q - dp / R with C the
    line's V / beta, or T_min (1 / R + g) where the land's conductance g = |q| / (2 |its drop|) and R make the
    drop relax faster than a sub-step (the compiled model copies a term's text)."""
    pressures, flow, land_drop, reads = _PORT[port]
    return [f"def land_pressures(p_sup, p_ret, dp_line):\n    return {pressures}\n",
            f"def state_rates({reads}, beta, dp_line, V_line, R_line, T_min):\n"
            f"    q = {flow}\n"
            f"    g = abs(q) / (2.0 * max(abs({land_drop}), 1.0e3))\n"
            "    cap = max(V_line / beta, T_min * (1.0 / R_line + g))\n"
            "    return (q - dp_line / R_line) / cap\n"]


def _port_line(port: str, name: str, where: str) -> type:
    """The line volume at the valve's ``port`` (:func:`_port_line_texts`)."""
    body = {"name": name, "port": port, "where": where, "__module__": __name__, "__qualname__": f"Line{port.title()}",
            "title": f"volume with a resistance in the {port} line",
            "__doc__": f"The line volume at the valve's {port} port.", **term_methods(name, _port_line_texts(port))}
    return type(PortLine)(body["__qualname__"], (PortLine,), body)


LineSupply = _port_line("supply", "aug_line_supply",
                        "the supply line (between the supply's gauge and the valve's pressure port)")
LineReturn = _port_line("return", "aug_line_return",
                        "the return line (between the valve's tank port and the tank)")


#: play in a joint: the library's effect (rod-crank joint), tried by the state stage with the others
PLAY = ("backlash",)


def augmentations() -> list[str]:
    """The names of the generic augmentations, one per kind and place, in the order the state stage tries them.

    Returns
    -------
    list of str
        Effect names (registered): the lags and the rate limit, the links, the hoses, the play, the other
        followers and the reading blocks, then the static terms at the balances
        (:mod:`ehas_env.physics.balance_blocks`, known here by their ``balance_place``: that module builds on this
        one).
    """
    from ehas_env.physics.effects.base import REGISTRY

    first = ["aug_lag_coil", "aug_slew_coil", "aug_lag_position_sensor"]  # the usual ones, tried first
    order = (LinkRodCrank, LinkMount, HoseAB, HoseA, HoseB, LineSupply, LineReturn)
    balances = [n for n, c in REGISTRY.items() if getattr(c, "balance_place", None) is not None]
    return (first + [c.name for c in order] + list(PLAY) + [n for n in followers() if n not in first]
            + reading_blocks() + balances)
