"""``ehas model``: read, write and compare model files (docs/model-file.md).

    ehas model show [FILE]                      every number with its unit (no FILE: the book's rig)
    ehas model new FILE [--from FILE] [--crank-radius-mm 60 ...] [--effects ...] [--name NAME]
    ehas model diff A B                         the fields that differ (status 1 when any)

A model file is the plant everywhere: ``--model FILE`` on simulate, tune, bench,
compare, diagnose, simulate-campaign, curves, size and train, ``model=`` in
``Plant`` and the environment.
"""
from __future__ import annotations

import argparse
import shlex
import sys

#: option name -> model-file key, for ``ehas model new``
def _option(key: str) -> str:
    return "--" + key.replace("_", "-")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ehas_env.ranges import Number

    try:
        from ehas_env.simulation.model_file import FIELDS
    except ImportError:  # a broken installation: the other commands still parse
        FIELDS = ()

    sub = parser.add_subparsers(dest="action", metavar="ACTION")
    sub.required = True
    show = sub.add_parser("show", help="print a model file's numbers with units (default: the book's rig)")
    show.add_argument("file", nargs="?", default=None, metavar="FILE")
    show.add_argument("--json", action="store_true", help="print the (version-2) JSON instead")
    new = sub.add_parser("new", help="write a model file: the book's rig (or --from FILE) with the numbers given")
    new.add_argument("file", metavar="FILE", help="model file to write (.json)")
    new.add_argument("--from", dest="base", default=None, metavar="FILE", help="start from this model file")
    new.add_argument("--name", default=None, help="the model's name (titles and tables show it)")
    new.add_argument("--description", default=None, help="free text")
    for f in FIELDS:
        new.add_argument(_option(f.key), dest=f.key, type=Number(_option(f.key), f.range), default=None,
                         help=f"{f.text}, {f.unit} (book {f.default:g}; {f.range.describe()})")
    new.add_argument("--rated-flow-lpm", type=Number("--rated-flow-lpm", _flow_range()), default=None,
                     help="rated valve flow at the rated drop and current, LPM (sets K = flow / rated current)")
    new.add_argument("--valve", choices=("grey_box", "white_box"), default=None, help="valve model")
    new.add_argument("--effects", default=None, help="effects of the plant, e.g. coulomb_friction:Fc=300 ('' for none)")
    for p in (show, new):
        p.add_argument("--effects-path", action="append", default=None, metavar="DIR",
                       help="folder (or .py file) of your own effect files the model needs (loaded first; the file "
                            "records their names and SHA-256, never the code or the folder); repeatable")
    new.add_argument("--overwrite", action="store_true", help="replace an existing FILE")
    diff = sub.add_parser("diff", help="the fields in which two model files differ (exit status 1 when they do); "
                                       "with one file: what it changes from the book's rig, with 95 % intervals")
    diff.add_argument("a", metavar="A")
    diff.add_argument("b", metavar="B", nargs="?", default=None)
    diff.add_argument("--effects-path", action="append", default=None, metavar="DIR",
                      help="folder (or .py file) of your own effect files the models need; repeatable")


def _flow_range():
    from ehas_env.ranges import Range

    return Range(0, 1e5, "LPM", lo_open=True)


def _given(value, name: str):
    """A path argument as given; an empty one is refused by its name (the nested parser is not checked by
    ``ehas``'s own empty-value check)."""
    if value is not None and not str(value).strip():
        raise ValueError(f"{name}: the path is empty; give a model JSON file (docs/model-file.md)")
    return value


def book_difference(model) -> tuple[list[str], bool]:
    """Lines saying what a model file changes from the book's rig: the recalibrated numbers and the effects with
    their units and 95 % intervals (the diagnosis' model difference), then any other field of the rig.

    Parameters
    ----------
    model : ehas_env.simulation.model_file.PlantModel
        A loaded model file.

    Returns
    -------
    lines : list of str
        A heading and one line per difference ("nothing" when the model is the book's rig).
    differs : bool
        Whether the model differs from the book's rig.
    """
    from ehas_env.measurement.model_difference import difference_text, model_difference
    from ehas_env.simulation import model_file as mf

    doc = {"effects": model.effects, "beta": model.value(mf.FIELD_BY_KEY["bulk_modulus_Pa"]),
           "K": model.value(mf.FIELD_BY_KEY["K_lpm_per_mA"]),
           "ci95": (model.calibration or {}).get("ci95") or []}
    own = {"rig.bulk_modulus_Pa", "valve.K_lpm_per_mA"}
    rest = [ln for ln in mf.diff_models(mf.PlantModel(), model)
            if not ln.startswith(("name:", "effects.", "user_effects.", "calibration:", "provenance:"))
            and ln.split(":")[0] not in own]
    rows = model_difference(doc)
    text = difference_text(rows, title=model.label).splitlines()
    if rest and not rows:
        text.pop()  # the "nothing" line
    return text + ["  " + ln for ln in rest], bool(rows or rest)


def run(args) -> int:
    from ehas_env.simulation import model_file as mf

    for attr, name in (("file", "FILE"), ("base", "--from"), ("a", "A"), ("b", "B")):
        _given(getattr(args, attr, None), name)
    if args.action == "show":
        m = mf.load_model(args.file) if args.file is not None else mf.PlantModel()
        if args.json:
            import json

            print(json.dumps(m.to_dict(), indent=2))
        else:
            print(m.summary())
        return 0
    if args.action == "diff" and args.b is None:
        lines, differs = book_difference(mf.load_model(args.a))
        print("\n".join(lines))
        return 1 if differs else 0
    if args.action == "diff":
        a, b = mf.load_model(args.a), mf.load_model(args.b)
        lines = mf.diff_models(a, b)
        print(f"--- {args.a} ({a.name})\n+++ {args.b} ({b.name})")
        print("\n".join(lines) if lines else "no difference")
        return 1 if lines else 0
    # new
    from pathlib import Path

    from ehas_env.output.outputs import check_file

    check_file(args.file, "FILE", overwrite=args.overwrite)
    base = mf.load_model(args.base) if args.base is not None else mf.PlantModel()
    doc = base.to_dict()
    for f in mf.FIELDS:
        v = getattr(args, f.key)
        if v is not None:
            doc[f.section][f.key] = v
    if args.rated_flow_lpm is not None:
        if args.K_lpm_per_mA is not None:
            raise ValueError("--rated-flow-lpm and --K-lpm-per-mA both set the valve gain; give one of them")
        doc["valve"]["K_lpm_per_mA"] = args.rated_flow_lpm / float(doc["valve"]["rated_current_mA"])
    if args.valve:
        doc["valve"]["model"] = args.valve
    if args.name is not None:
        doc["name"] = args.name
    elif not args.base:
        doc["name"] = Path(args.file).stem
    if args.description is not None:
        doc["description"] = args.description
    if args.effects is not None:  # user effects were loaded from --effects-path before the command ran
        from ehas_env.physics.effects import parse_spec

        doc["effects"] = parse_spec(args.effects) if args.effects else {}
    doc["user_effects"] = mf.user_effects_of(doc["effects"])
    doc["calibration"] = {} if not args.base else doc.get("calibration", {})
    argv = sys.argv[1:]
    command = "ehas " + " ".join(shlex.quote(a) for a in argv) if argv[:2] == ["model", "new"] else None
    doc["provenance"] = mf.provenance(command, **({"based_on": base.label} if args.base else {}))
    m = mf.parse_model(doc, str(args.file))
    path = mf.write_model(args.file, m)
    print(m.summary())
    print(f"wrote {path}")
    return 0
