"""proposed_p1_rate_limit_load_reading_smooth_piston_force: a term proposed by ehas diagnose for /tmp/drawnBw/p1_rate_limit@load_reading+smooth@piston_force/campaign.

F_piston [N] += c_vv·v |v|   with c_vv = -2251 N s^2/m^2 (95 % CI -2278 to -2224)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 5.36 -> 1.86; fit 90.2 % -> 96.2 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP1RateLimitLoadReadingSmoothPistonForce(Effect):
    name = "proposed_p1_rate_limit_load_reading_smooth_piston_force"
    title = "proposed term (piston force)"
    params = (
        Param("f_vv", "N s^2/m^2", 2251.38, (0.0, 45027.6),
              "quadratic damping: force per (m/s)^2, signed (fitted: -2251, 95 % CI -2278 to -2224)", typical=(1125.69, 4502.76)),
    )
    main_param = "f_vv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_vv·v |v| with c_vv = -2251 N s^2/m^2 (95 % CI -2278 to -2224)'
    signature = 'the residual it was fitted to: v |v|'

    @staticmethod
    def piston_force(v, f_vv):
        return -(f_vv * v * abs(v))
