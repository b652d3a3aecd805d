"""The base of the generated augmentations: a kind of block at a place, its words, and the terms written as source.

The kinds (:mod:`ehas_env.physics.augment`: followers in a signal path, static blocks at a reading, links and
hoses; :mod:`ehas_env.physics.balance_blocks`: static terms at a balance) build on :class:`Augmentation` and write
each place's terms as Python text (:func:`term_functions`), which the compiled model copies like any effect file's.
It lives in the effects package, beside :class:`~ehas_env.physics.effects.base.Effect`, so that the modules of
kinds import it and not each other.
"""
from __future__ import annotations

import math
from typing import ClassVar

from ehas_env.physics.effects.base import Effect


def fmt_interval(v: float, ci, scale: float = 1.0) -> str:
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
            return f"{fmt_interval(params[q.name], ci.get(q.name), scale)} {unit}"

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


def term_functions(label: str, text: str) -> dict:
    """The functions defined by ``text``, their source findable (``inspect.getsource``) under ``label``: the
    compiled model copies a term's source text."""
    import linecache

    filename = f"<ehas_env.physics.generated: {label}>"
    linecache.cache[filename] = (len(text), None, text.splitlines(True), filename)
    namespace = {"math": math}
    exec(compile(text, filename, "exec"), namespace)
    return {k: v for k, v in namespace.items() if callable(v) and getattr(v, "__code__", None)
            and v.__code__.co_filename == filename}


def term_methods(name: str, texts) -> dict:
    """The terms of the effect ``name`` written as ``texts`` (each ``def <model place>(...)``), as the static methods
    of its class: {function name: staticmethod}, each findable under ``<name>.<place>`` (:func:`term_functions`)."""
    out = {}
    for text in texts:
        out.update({k: staticmethod(v) for k, v in term_functions(f"{name}.{text[4:text.index('(')]}", text).items()})
    return out


def kind_at(kind: type, short: str, name: str, where: str, texts, body: dict, module: str | None = None) -> type:
    """The effect class ``name`` that puts the kind of block ``kind`` at a place: the one builder of the generated
    augmentations (a follower or a static block at a signal, :mod:`ehas_env.physics.augment`; a static term at a
    balance, :mod:`ehas_env.physics.balance_blocks`).

    Parameters
    ----------
    kind : type
        The kind's class (an :class:`Augmentation` subclass with ``kind_title``).
    short, where : str
        The place in the class's name, and in words (the effect's ``where``; its title is the kind's in it).
    name : str
        The effect's name (``aug_<stem>_<short>``).
    texts : iterable of str
        The source of its terms, each ``def <model place>(...)`` (:func:`term_functions`: the compiled model copies
        a term's text).
    body : dict
        Its attributes of the place and kind (``params``, ``shown``, the place's description ...).
    module : str, optional
        The module that owns it (default the kind's; a user's file that puts a kind at a place of its own owns the
        effects it makes: the effect loader finds a file's effects by their module).

    Returns
    -------
    type
        The subclass of ``kind``, registered by its creation.
    """
    body = {"name": name, "title": f"{kind.kind_title} in {where}", "where": where,
            "__module__": module or kind.__module__, "__qualname__": f"{kind.__name__}At_{short}",
            "__doc__": f"{kind.kind_title} in {where} (generated by {kind.__name__}.at).", **body,
            **term_methods(name, texts)}
    return type(kind)(body["__qualname__"], (kind,), body)
