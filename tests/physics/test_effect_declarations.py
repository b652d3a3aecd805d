"""An effect's declaration and terms are checked when it registers (issue 14: one line naming the effect,
the field or term, and what is allowed); the library's effects and a user's file are held to the same rules."""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from ehas_env.physics.effects import REGISTRY, Effect, Param
from ehas_env.physics.effects.example_file import spring_effect
from refusals import refused

K = Param("k", "N m/rad", 2000.0, (0.0, 1.0e6), "spring rate", typical=(500.0, 5000.0))


def define(name="decl_spring", params=(K,), main_param="k", body=None, **attrs):
    """Define (and so register) an effect class like the docs' torsion spring, with some fields changed."""
    def crank_torque(theta, k):
        return -(k * theta)

    ns = {"name": name, "title": "spring", "params": params, "main_param": main_param,
          "crank_torque": staticmethod(crank_torque), **attrs}
    if body is not None:
        del ns["crank_torque"]
        ns.update(body)
    return type("DeclSpring", (Effect,), ns)


def test_the_library_passes_its_own_rules():
    library = [c for c in REGISTRY.values() if c.__module__.startswith("ehas_env.physics.effects.")]
    # one effect per file of the effects folder (its machinery files aside): 13 effects, the rest hypotheses
    import ehas_env.physics.effects as fx
    files = {f.stem for f in Path(fx.__file__).parent.glob("*.py")} - {"__init__", "base", "loading", "example_file",
                                                                       "augmentation"}
    assert sorted(c.__module__.rsplit(".", 1)[1] for c in library) == sorted(files)
    assert sum(c.kind != "hypothesis" for c in library) == 13
    for cls in library:
        cls._check_declaration()
        cls._check_terms()
        assert cls.main_param in [p.name for p in cls.params]


@pytest.mark.parametrize("param, patterns", [
    (Param("k", "N", -5.0, (0.0, 1.0e6), "d"), ("parameter 'k'", "default -5 is outside its bounds [0, 1e+06]")),
    (Param("k", "N", 1.0, (1.0e6, 0.0), "d"), ("parameter 'k'", "reversed", "low <= high")),
    (Param("k", "N", 1.0, (0.0, math.inf), "d"), ("parameter 'k'", "bounds must be (low, high), two finite")),
    (Param("k", "N", math.nan, (0.0, 1.0), "d"), ("parameter 'k'", "default must be a finite number")),
    (Param("k", "N", 1.0, (0.0,), "d"), ("parameter 'k'", "bounds must be (low, high)")),
    (Param("k", "N", 1.0, (0.0, 2.0), "d", typical=(1.0, 5.0)), ("parameter 'k'", "typical (1, 5)", "inside")),
    (Param("k", "N", 1.0, (0.0, 2.0), "d", si=0.0), ("parameter 'k'", "si must be a positive number")),
    (Param("k-1", "N", 1.0, (0.0, 2.0), "d"), ("name 'k-1' is not allowed", "letters, digits and _")),
])
def test_bad_parameter_declarations_are_refused(param, patterns):
    msg = refused(lambda: define(params=(param,), main_param=""), "effect 'decl_spring'", *patterns)
    assert "class DeclSpring" in msg
    assert "decl_spring" not in REGISTRY


@pytest.mark.parametrize("name", ["fc-spring", "fc spring", "2spring", ""])
def test_effect_names_must_be_identifiers(name):
    if not name:  # an empty name is an abstract base, not an effect: nothing registers
        define(name="")
        return
    refused(lambda: define(name=name), f"name '{name}' is not allowed", "letters, digits and _",
            "not starting with a digit", "class DeclSpring")
    assert name not in REGISTRY


def test_params_must_be_a_tuple_of_param():
    refused(lambda: define(params=K), "effect 'decl_spring'", "params must be a tuple of Param", "got Param")
    refused(lambda: define(params=(K, "k")), "params[1] must be a Param(...), got str")


def test_main_param_must_name_a_parameter():
    refused(lambda: define(main_param="kk"), "effect 'decl_spring'", "main_param 'kk' is not one of its parameters (k)")


def test_two_parameters_with_one_name_are_refused():
    refused(lambda: define(params=(K, Param("k", "N", 1.0, (0.0, 2.0), "dup"))),
            "effect 'decl_spring'", "'k' is declared twice (in params)")
    refused(lambda: define(constants=(Param("k", "N", 1.0, (0.0, 2.0), "dup"),)),
            "'k' is declared twice (in params and constants)")


def test_defaults_must_pass_the_effects_own_validate():
    def validate(cls, values):
        raise ValueError("effect 'decl_spring': k must be above 1e7")

    refused(lambda: define(validate=classmethod(validate)), "defaults fail its own validate()", "above 1e7")


@pytest.mark.parametrize("body, patterns", [
    ({"chamber_flows": staticmethod(lambda theta, k: -(k * theta))},
     ("term chamber_flows returned float", "must return a tuple of 2 numbers", "chamber A")),
    ({"crank_torque": staticmethod(lambda theta, k: (k, theta))},
     ("term crank_torque returned a tuple of 2", "must return one number", "torque")),
    ({"crank_torque": staticmethod(lambda theta, k: k / 0.0)},
     ("term crank_torque(theta=0.2, k=2000) raised ZeroDivisionError",)),
    ({"crank_torque": staticmethod(lambda theta, k: math.nan)}, ("term crank_torque", "not a finite number")),
    ({"crank_torque": staticmethod(lambda thetaa, k: k)}, ("argument 'thetaa' of its term 'crank_torque'",)),
    ({"valve_current": staticmethod(lambda i, theta, k: i)}, ("argument 'theta' of its term 'valve_current'",)),
    ({"crank_torque": staticmethod(lambda theta, k: REGISTRY_SCALE * k)},
     ("term crank_torque uses 'REGISTRY_SCALE' from its file", "constants")),
    ({"crank_torque": staticmethod(lambda theta, k: no_such_name * k)},  # noqa: F821
     ("term crank_torque uses 'no_such_name', which its file does not define",)),
    ({"state_rates": staticmethod(lambda theta, k: -k)}, ("state_rates", "declares no states")),
])
def test_terms_are_called_once_and_must_return_what_their_place_takes(body, patterns):
    refused(lambda: define(body=body), "effect 'decl_spring' (class DeclSpring)", *patterns)
    assert "decl_spring" not in REGISTRY


REGISTRY_SCALE = 2.0


def test_a_state_rate_per_state():
    states = (("a", "-", 0.0), ("b", "-", 0.0))
    refused(lambda: define(states=states, body={"state_rates": staticmethod(lambda a, b, k: -a)}),
            "term state_rates returned float", "a tuple of 2 numbers")
    refused(lambda: define(states=(("a", "-", math.inf),), body={"state_rates": staticmethod(lambda a: -a)}),
            "states[0] must be (name, unit, initial value in SI)")


EFFECT_OK = spring_effect()


@pytest.mark.parametrize("edit, patterns", [
    (("2000.0, (0.0, 1.0e6)", "-5.0, (0.0, 1.0e6)"), ("fc_spring", "parameter 'k'", "outside its bounds")),
    (('"fc_spring"', '"fc-spring"'), ("'fc-spring' is not allowed", "letters, digits and _")),
    (("params = (Param(", "params = Param("), ("fc_spring", "params must be a tuple of Param")),
    (("def crank_torque(theta, k)", "def chamber_flows(theta, k)"),
     ("fc_spring", "term chamber_flows returned float", "a tuple of 2 numbers")),
    (("return -(k * theta)", "return -(k * np.tanh(theta))"), ("fc_spring", "'np'", "does not define")),
])
def test_a_user_effect_file_is_refused_in_one_line(tmp_path, edit, patterns):
    from ehas_env.physics.effects import load_effects_path

    text = EFFECT_OK.replace(*edit)
    if edit[0] == "params = (Param(":
        text = text.replace('typical=(500.0, 5000.0)),)', 'typical=(500.0, 5000.0))')
    (tmp_path / "spring.py").write_text(text)
    refused(lambda: load_effects_path(tmp_path), "spring.py", "class FcSpring", *patterns)
    assert "fc_spring" not in REGISTRY and "fc-spring" not in REGISTRY


def test_the_command_line_refuses_a_bad_effect_file_with_status_2(tmp_path, capsys):
    from ehas_env.cli.main import main

    (tmp_path / "spring.py").write_text(EFFECT_OK.replace('main_param = "k"', 'main_param = "kk"'))
    assert main(["effects", "--effects-path", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("ehas effects: error: --effects-path: effect file ")
    assert "spring.py" in err[0] and "main_param 'kk' is not one of its parameters (k)" in err[0]


@pytest.mark.parametrize("value, got", [(3, "int"), (lambda theta, k: -(k * theta), "function")])
def test_a_place_must_hold_a_static_method(value, got):
    # a number, or a method without @staticmethod, at a place would be skipped without a word
    refused(lambda: define(body={"crank_torque": value}), "effect 'decl_spring'",
            f"crank_torque must be a @staticmethod", f"got {got}")


def test_an_argument_that_names_nothing_is_refused_where_the_compiler_would():
    # one resolver (Effect.arg_kind) for the check at registration and the code generator
    def piston_force(vv, k):
        return k * vv

    refused(lambda: define(body={"piston_force": staticmethod(piston_force)}), "effect 'decl_spring'",
            "argument 'vv' of its term 'piston_force' is neither one of its parameters", "nor a baseline slot")
    cls = REGISTRY["coulomb_friction"]
    assert [cls.arg_kind(a, "piston_force") for a in ("Fc", "v", "v_tanh")] == ["param", "quantity", "slot"]


def test_a_coil_effects_state_moves_with_the_current_alone():
    """A coil_current effect's states are integrated where the coil's current is, on the valve bench too (no
    load there): its state_rates may take the current, not the load's quantities."""
    def rates(i, z, p_load, k):
        return i - z + 0.0 * p_load

    refused(lambda: define(states=(("z", "mA", 0.0),), body={"state_rates": staticmethod(rates),
                                                            "coil_current": staticmethod(lambda z: z)}),
            "argument 'p_load' of its term 'state_rates'", "available there (i)")
    assert REGISTRY["hyp_coil_lag"].arg_kind("i", "state_rates") == "quantity"


@pytest.mark.parametrize("value", ["transport_delay", ("transport delay",), (3,)])
def test_mistaken_for_names_effects(value):
    refused(lambda: define(mistaken_for=value), "mistaken_for must be a tuple of effect names")
