"""Static blocks at a logged reading, applied to a replay of the rest of the model (issue 44, point 3: reuse what
a candidate does not change).

A static block at a sensor's reading (:class:`ehas_env.physics.augment.Static`: an offset, a scale error, a clip, a
dead zone, a knee, a cubic bend of chamber A's pressure reading, the flow meter's, the load reading...) changes
what the logger records and nothing else: the controller feeds back the model's states, not these readings
(:func:`ehas_env.simulation.loops` takes the load pressure from the chambers' states); the valve bench's flow is
metered through the same flow meter (the ports joined through it), so a block at the flow meter's reading acts
on a valve run's flow too.  Its effect on a replay is therefore its term applied to the replay of the model without it,
sample by sample -- what the compiled model does inside ``measure`` -- and a screen or a fit of such a block's own
parameters needs one replay of the rest, not one per value tried.  The term is the block's own Python function,
evaluated on whole arrays (its ``min`` and ``max`` elementwise); the replay of the rest is cached by the
:class:`~ehas_env.measurement.replay.Replayer`.

Only where nothing else acts at the reading (the compiled chain's order would decide), on runs the replayer does
not resample (a clip applied after the interpolation is not the clip before it), and for models without proposed
terms; every other model is replayed whole.
"""
from __future__ import annotations

import functools
import types

import numpy as np

from ehas_env.physics.effects import get_effect
from ehas_env.physics.effects.base import effect_slots
from ehas_env.physics.layout import SENSED
from ehas_env.physics.rig import BAR, LPM

#: each logged reading place: the replay's signal that records it and that signal's unit in SI (x it)
READING_SIGNALS = {"pa_reading": ("p_a_bar", BAR), "pb_reading": ("p_b_bar", BAR), "ps_reading": ("p_s_bar", BAR),
                   "flow_a_reading": ("flow_lpm", LPM), "force_reading": ("load_kN", 1.0e3)}
assert set(READING_SIGNALS) == {f"{out}_reading" for out in SENSED}, "a sensed output without its replay signal"


@functools.lru_cache(maxsize=None)
def _array_term(name: str):
    """(the place, the term of effect ``name`` on arrays, its parameters' names) when ``name`` is a static block
    at a logged reading whose term takes the reading and its own parameters alone and gives on arrays what it
    gives sample by sample; else None."""
    from ehas_env.physics.augment import Static

    cls = get_effect(name)
    if not (isinstance(cls, type) and issubclass(cls, Static)):
        return None
    terms = cls.terms()
    if len(terms) != 1:
        return None
    (place, f), = terms.items()
    if place not in READING_SIGNALS:
        return None
    args = cls.term_args(place)
    if [cls.arg_kind(a, place) for a in args] != ["quantity"] + ["param"] * (len(args) - 1):
        return None
    g = types.FunctionType(f.__code__, {**f.__globals__, "min": np.minimum, "max": np.maximum}, f.__name__,
                           f.__defaults__, f.__closure__)
    # the same numbers on arrays as sample by sample, at values about the reading's span and the defaults
    span = cls.signal_place.span
    u = np.array([-1.3, -0.4, -0.01, 0.0, 0.02, 0.5, 1.7]) * span
    params = [effect_slots(name, None)[f"{name}.{a}"] for a in args[1:]]
    try:
        same = np.array_equal(g(u, *params), np.array([f(float(x), *params) for x in u]))
    except Exception:  # a term that numpy cannot evaluate on arrays: replayed whole
        return None
    return (place, g, tuple(args[1:])) if same else None


def split(effects: dict, others=()) -> tuple[dict, list] | None:
    """``effects`` ({name: {param: value}}) parted into the rest and the static blocks at logged readings that
    may be applied to the rest's replay; None when there are none (or they may not be: two at one reading, or
    another effect acting there too).

    Parameters
    ----------
    effects : dict
        A model's effects.
    others : iterable of str
        Effects the model holds besides (a model file's own): none of them may act at the blocks' readings.

    Returns
    -------
    (dict, list) or None
        The other effects, and [(name, place, term on arrays, its parameters' SI values)].

    Examples
    --------
    >>> rest, blocks = split({"coulomb_friction": {"Fc": 300.0}, "aug_offset_pa_reading": {"c": 1.0e5}})
    >>> list(rest), [(n, p) for n, p, _, _ in blocks]
    (['coulomb_friction'], [('aug_offset_pa_reading', 'pa_reading')])
    >>> split({"coulomb_friction": {"Fc": 300.0}}) is None
    True
    """
    blocks, rest = [], {}
    for name, values in effects.items():
        term = _array_term(name)
        if term is None:
            rest[name] = values
            continue
        place, g, pnames = term
        slots = effect_slots(name, get_effect(name).resolve(values))
        blocks.append((name, place, g, tuple(slots[f"{name}.{p}"] for p in pnames)))
    if not blocks:
        return None
    places = [b[1] for b in blocks]
    if len(set(places)) < len(places) or any(p in get_effect(n).terms() for n in [*rest, *others] for p in places):
        return None
    return rest, blocks


def apply(sims: list, blocks: list) -> list:
    """The replay ``sims`` (every run's signals; None where not simulated) of the rest of a model with its static
    blocks at logged readings ``blocks`` (from :func:`split`) applied: the closed-loop runs' reading signals
    through each block's term (in SI); a valve run its flow alone, metered through the same flow meter.

    Parameters
    ----------
    sims : list of dict or None
    blocks : list

    Returns
    -------
    list of dict or None
        New dicts (``sims`` is left as it is).
    """
    out = []
    for sim in sims:
        if sim is None:
            out.append(sim)
            continue
        sim = dict(sim)
        for _, place, g, values in blocks:
            signal, si = READING_SIGNALS[place]
            if signal in sim:  # a valve run records the flow meter's reading alone
                sim[signal] = np.asarray(g(sim[signal] * si, *values), dtype=float) / si
        out.append(sim)
    return out
