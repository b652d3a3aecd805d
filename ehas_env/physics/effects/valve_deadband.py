"""Spool overlap seen as a current deadband."""
import math

from ehas_env.physics.effects.base import Effect, Param


class ValveDeadband(Effect):
    name = "valve_deadband"
    title = "valve deadband (overlapped spool)"
    params = (
        Param("d", "mA", 0.5, (0.0, 10.0), "half-width of the deadband in amplifier current (assumed; the rig's valve has negligible deadband)",
              typical=(0.3, 1.5)),
    )
    smooth = False
    main_param = "d"
    explanation = (
        "An overlapped spool has lands wider than its ports: the spool must move some distance before any "
        "port opens. Seen from the amplifier this is a current deadband, i -> sign(i) max(|i| - d, 0): "
        "small commands give no flow, and every command loses d mA."
    )
    signature = (
        "zero flow while |current| < d (valve runs: flow vs current is flat around zero); in closed "
        "loop the current residual is a square wave of +-d in phase with the current's sign, and "
        "position error bumps where the flow reverses."
    )

    chain_order = 0  # before the null bias: the bias is an offset of the spool, after the deadband

    @staticmethod
    def valve_current(i, d):
        a = abs(i) - d
        return math.copysign(a, i) if a > 0.0 else 0.0
