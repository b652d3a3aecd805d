"""Null bias of the servo valve."""
from ehas_env.physics.effects.base import Effect, Param


class ValveNullBias(Effect):
    name = "valve_null_bias"
    title = "valve null bias"
    params = (
        Param("i_bias", "mA", 0.3, (-5.0, 5.0), "current the valve behaves as if added to every command (assumed)",
              typical=(0.2, 1.0)),
    )
    main_param = "i_bias"
    explanation = (
        "A valve whose mechanical null is off-centre (feedback-wire set, torque-motor magnetism, wear) "
        "passes flow at zero command, as if i_bias were added to every current. A position loop hides "
        "it by holding an integrator offset of -i_bias."
    )
    signature = (
        "closed loop: a constant offset of -i_bias in the logged current (the integrator cancels the bias); "
        "valve runs: flow offset K i_bias at zero current; residual mean not zero."
    )

    chain_order = 10

    @staticmethod
    def valve_current(i, i_bias):
        return i + i_bias
