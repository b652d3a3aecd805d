"""The static kinds: a static block at a sensor's reading, each kind defined once and applied at every reading it
fits (:data:`ehas_env.physics.augment.READING_PLACES`): an **offset**, a **scale error**, a **saturation**, a **dead
zone** and a **slope change beyond a knee** (piecewise-linear), what the sensor reports an expression of the
model's output ``u`` (:class:`Static`).  A new kind is one class with its expression (:func:`reading_blocks`).
"""
from __future__ import annotations

from typing import ClassVar

from ehas_env.physics.augment import READING_PLACES, Augmentation, SignalPlace, _block_class, _fmt
from ehas_env.physics.effects.base import Param


class Static(Augmentation):
    """A kind of static block at a sensor's reading: what the sensor reports is ``expr`` of the model's output
    ``u`` and the kind's parameters (no state).  :meth:`at` puts it at a reading place (:data:`READING_PLACES`);
    the position sensor's and the coil's static errors are the library's (``hyp_position_offset``,
    ``hyp_position_shape``, ``valve_null_bias``)."""

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
        text = (f"def {place.place}({place.value}, {args}):\n    u = {place.value}\n    return {cls.expr}\n")
        return _block_class(cls, place, name, (text,), {})


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
        # from a twentieth of the span (a range far too small) to five spans (never reached: no effect)
        return (Param("L", place.unit, 5.0 * place.span, (0.05 * place.span, 5.0 * place.span),
                      f"the largest value the reading reports either way, {place.unit} (assumed range: 0.05 to 5 "
                      f"times the signal's span of {place.span:g} {place.unit}; the default, 5 spans, is never "
                      "reached: no effect)", typical=(0.3 * place.span, 2.0 * place.span), log_scale=True),)

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


#: the static kinds, each applied at every sensed output's reading it fits
STATIC_KINDS = (Offset, Gain, Saturation, DeadZone, Knee)
STATICS = tuple(kind.at(place) for kind in STATIC_KINDS for place in READING_PLACES if kind.fits(place))


def reading_blocks() -> list[str]:
    """The names of every static kind at every sensor's reading (:data:`STATIC_KINDS` x :data:`READING_PLACES`),
    and those a user's file made with :meth:`Static.at`.

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
