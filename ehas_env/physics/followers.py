"""The follower kinds: a state in a signal path, each kind defined once and applied at every signal place
(:data:`ehas_env.physics.augment.SIGNAL_PLACES`).

A :class:`Follower`'s signal passed on, ``y``, follows the signal that comes, ``u``, by a law of their gap: a
**lag** (:class:`Lag`, a first-order filter ``T y' = u - y``: a coil's inductance, an LVDT demodulator's filter, a
pressure transducer's), a **rate limit** (:class:`RateLimit`: an amplifier's voltage headroom, a conditioner's slew
rate), a **pure delay** (:class:`Delay`, a first-order Pade all-pass: a converter's latency) and a **play**
(:class:`Play`, backlash of half width ``b``: a torque motor's hysteresis, a gauge's play).  A new kind is one class
with its law; a new sensed output is a new place for every kind (:func:`followers`).  A follower at a place whose
signal has a rate in the model keeps the error between what it passes on and what comes (0 at rest, whatever the
position or pressure a run starts from); at the coil it keeps the current itself (0 mA at rest).
"""
from __future__ import annotations

import math
from typing import ClassVar

from ehas_env.physics.augment import SIGNAL_PLACES, Augmentation, SignalPlace, _block_class
from ehas_env.physics.effects.base import Param


class Follower(Augmentation):
    """A kind of state in a signal path: the signal passed on, ``y``, follows the signal that comes, ``u``, by a law
    of the gap ``d = u - y``: ``y' = law(d)``.  One class per kind holds its parameters, words and law (a Python
    expression in ``d`` and its parameters); :meth:`at` makes the effect that puts it at a :class:`SignalPlace`,
    and :func:`followers` the whole product.  Where the place has a rate for its signal, the state is the error
    ``e = y - u`` (``e' = law(-e) - u'``, 0 at rest wherever the run starts), else ``y`` itself from rest."""

    #: y' as a Python expression of the gap d = u - y and the kind's parameters and constants
    law: ClassVar[str] = ""
    #: the kind in an effect's name and in its state's name
    stem: ClassVar[str] = ""
    #: the kind's title, before "in <place>"
    kind_title: ClassVar[str] = ""
    #: the effects a follower of this kind in the loop may be mistaken for (its ``mistaken_for`` there)
    loop_rivals: ClassVar[tuple] = ()
    #: what is passed on is ``u + through * (y - u)``: 1 passes the follower's output ``y``; 2 passes ``2 y - u``,
    #: the all-pass a first-order Pade delay is (:class:`Delay`), which needs the place's rate (the error form)
    through: ClassVar[float] = 1.0
    #: whether the kind needs the place's rate (the error form) to be put there
    needs_rate: ClassVar[bool] = False

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
            rates = (f"def state_rates({place.rate}, {state}, {args}):\n    d = -{state}\n"
                     f"    return {cls.law} - {place.rate}\n")
            gain = "" if cls.through == 1.0 else f"{cls.through!r} * "
            passed = f"def {place.place}({place.value}, {state}):\n    return {place.value} + {gain}{state}\n"
        else:  # y itself, from rest
            state = f"{place.value}_{cls.stem}"
            rates = f"def state_rates({place.value}, {state}, {args}):\n    d = {place.value} - {state}\n    return {cls.law}\n"
            passed = f"def {place.place}({state}):\n    return {state}\n"
        body = {"states": ((state, place.unit, 0.0),)}
        if place.place == "position_reading":
            # after the sensor's static effects (an offset, a shape): the state acts on what the conditioner outputs
            body["chain_order"] = 100
        # a follower in the loop makes it late, as a delay of the command does: tried in place of one kept; at a
        # logged reading it moves that reading alone, which no delay of the command stands in for
        body["mistaken_for"] = cls.loop_rivals if place.in_loop else ()
        return _block_class(cls, place, name, (rates, passed), body)


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

    The follower ``y' = S tanh((u - y) / (S T_ss))``: a first-order follower of time constant T_ss for small
    steps, never faster than S for large ones (tanh keeps the right-hand side smooth for the integrator).  At the
    coil: a servo amplifier drives the torque motor's coil through its inductance with a bounded voltage, so the
    current rises at most (V_max - R i) / L, about constant (Jelali & Kroll 2003, the servo amplifier; Merritt
    1967, the torque motor); at a reading, a conditioner's slew-rate limit."""

    form = "a rate limit"
    stem = "slew"
    kind_title = "rate limit"
    law = "S * math.tanh(d / (S * T_ss))"
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
    needs_rate = True
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


#: the follower kinds, each applied at every signal place it can be put (a delay needs the place's rate)
FOLLOWER_KINDS = (Lag, RateLimit, Delay, Play)
#: the product, generated once (registered as effects when this module is imported)
FOLLOWERS = tuple(kind.at(place) for kind in FOLLOWER_KINDS for place in SIGNAL_PLACES
                  if place.rate or not kind.needs_rate)


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
