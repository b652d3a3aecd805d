"""proposed_d22_piecewise_linear_crank_torque: drag torque growing with the square of the crank rate, found by ehas diagnose on /work/runs/drawn/d22_piecewise_linear@crank_torque/campaign.

A drag torque on the load grows with the square of its speed: 12.4 N m at 10 rad/s.
T_10 = 12.36 N m (95 % CI 11.73 to 13.03)
Residual against what does not repeat: 2.3x -> 1.07x.
Next: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD22PiecewiseLinearCrankTorque(Effect):
    name = "proposed_d22_piecewise_linear_crank_torque"
    title = "drag torque growing with the square of the crank rate"
    params = (
        Param("T_10", "N m", 12.3643, (0.0, 2000.0),
              "drag torque on the crank at 10 rad/s (air or oil drag on the discs, a fan, a damper; assumed "
              "range: up to the torque the actuator gives at a fifth of its stall force)",
              typical=(6.18217, 24.7287), log_scale=True),
    )
    main_param = "T_10"
    explanation = (
        "Discs turning in air, a paddle in oil or a turbulent damper resist with a torque that grows with the "
        "square of the speed: T = -T_10 (omega / 10 rad/s)^2 sign(omega). At low speed it is negligible, at "
        "the peaks of fast runs it dominates; a viscous (linear) friction fitted to it comes out larger on "
        "the fast runs than on the slow ones."
    )
    signature = (
        "load residual proportional to omega |omega|: largest at the mid-stroke speed peaks of the fast, large "
        "runs and absent on slow ones; no step at reversals."
    )

    @classmethod
    def in_words(cls, params: dict) -> str:
        """The fitted hypothesis in words."""
        return (f"a drag torque on the load grows with the square of its speed: {params['T_10']:.3g} N m at "
                f"10 rad/s")

    @staticmethod
    def crank_torque(omega, T_10):
        return -T_10 * omega * abs(omega) * 0.01
