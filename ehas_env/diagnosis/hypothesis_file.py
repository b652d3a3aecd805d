"""A structural hypothesis the diagnosis kept, written as the user's own effect file.

The hypothesis effects of the library (``kind = "hypothesis"``, e.g. ``hyp_rod_area``) are copied with
their physical parameter names, units, bounds, explanation and residual signature; the copy is named
after the file (``DIR/NAME.py`` -> effect ``NAME``), is an ordinary ``physical`` effect, and its
parameters' defaults are the fitted values (the 95 % intervals in their documentation).
"""
from __future__ import annotations

import inspect
import re
import sys
from pathlib import Path

from ehas_env.physics.effects import get_effect


def hypothesis_source(effect: str, params: dict, name: str, *, origin: str = "", ci: dict | None = None,
                      words: str = "", before: float | None = None, after: float | None = None) -> str:
    """The text of a user effect file holding the fitted hypothesis ``effect`` under the name ``name``.

    Parameters
    ----------
    effect : str
        A hypothesis effect of the library (``hyp_rod_area`` ...).
    params : dict
        Its fitted values {param: value} (in the parameters' units).
    name : str
        The new effect's name (a Python identifier).
    origin : str
        The campaign it was found on (the docstring says so).
    ci : dict, optional
        {param: (low, high)}, 95 % intervals.
    words : str
        The fitted hypothesis in words.
    before, after : float, optional
        The residual (in what does not repeat) before and after it.

    Returns
    -------
    str
    """
    cls = get_effect(effect)
    src = inspect.getsource(sys.modules[cls.__module__])
    cls_name = "".join(p.capitalize() for p in name.split("_") if p) or "Found"
    if not cls_name[0].isalpha():
        cls_name = "Found" + cls_name
    src = src.replace(f"class {cls.__name__}(Effect):", f"class {cls_name}(Effect):", 1)
    src = src.replace(f'    name = "{effect}"', f'    name = "{name}"', 1)
    src = src.replace('    kind = "hypothesis"\n', "", 1)
    src = src.replace("from ehas_env.physics.effects.base import Effect, Param",
                      "from ehas_env.physics.effects import Effect, Param", 1)
    for p in cls.params:
        v = float(params.get(p.name, p.default))
        # the default becomes the fitted value (kept inside the bounds the declaration states)
        pat = re.compile(r'(Param\("' + re.escape(p.name) + r'", "[^"]*", )([^,]+)(,)')
        src = pat.sub(lambda m: f"{m.group(1)}{v:.6g}{m.group(3)}", src, count=1)
        if v != 0.0 and p.typical is not None:  # the typical range around the fitted value (the fit scans it)
            lo, hi = p.bounds
            t = (max(lo, abs(v) / 2.0), min(hi, 2.0 * abs(v)))
            if t[0] <= t[1]:
                tpat = re.compile(r'(Param\("' + re.escape(p.name) + r'".*?typical=\()([^)]*)(\))', re.S)
                src = tpat.sub(lambda m: f"{m.group(1)}{t[0]:.6g}, {t[1]:.6g}{m.group(3)}", src, count=1)
    head = [f'"""{name}: {cls.title}, found by ehas diagnose{(" on " + origin) if origin else ""}.', ""]
    if words:
        head.append(words[0].upper() + words[1:] + ".")
    for p in cls.params:
        v = params.get(p.name, p.default)
        lohi = (ci or {}).get(p.name)
        head.append(f"{p.name} = {v:.4g} {p.unit}" + (f" (95 % CI {lohi[0]:.4g} to {lohi[1]:.4g})" if lohi else ""))
    if before is not None and after is not None:
        head.append(f"Residual against what does not repeat: {before:.3g}x -> {after:.3g}x.")
    head += ["Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit", '"""']
    src = re.sub(r'\A"""(.*?)"""', lambda m: "\n".join(head), src, count=1, flags=re.S)
    return src


def write_hypothesis(path, effect: str, params: dict, **kw) -> Path:
    """Write :func:`hypothesis_source` to ``DIR/NAME.py`` (NAME names the effect); returns its path."""
    from ehas_env.output.files import atomic_write_text

    path = Path(path)
    name = path.stem
    if path.suffix != ".py" or not name.isidentifier():
        raise ValueError(f"--write-effect {path}: give DIR/NAME.py with NAME a Python identifier (it names the effect)")
    text = hypothesis_source(effect, params, name, **kw)
    compile(text, str(path), "exec")
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write_text(path, text)
