"""proposed_p1_rate_limit_load_reading_smooth_piston_force: a term proposed by ehas diagnose for /tmp/drawn-work/p1_rate_limit@load_reading+smooth@piston_force/campaign.

F_piston [N] += c_vv·v |v|   with c_vv = -2309 N s^2/m^2 (95 % CI -2338 to -2281)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 4.44 -> 1.67; fit 66.9 % -> 69.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP1RateLimitLoadReadingSmoothPistonForce(Effect):
    name = "proposed_p1_rate_limit_load_reading_smooth_piston_force"
    title = "proposed term (piston force)"
    params = (
        Param("f_vv", "N s^2/m^2", 2309.33, (0.0, 46186.7),
              "quadratic damping: force per (m/s)^2, signed (fitted: -2309, 95 % CI -2338 to -2281)", typical=(1154.67, 4618.67)),
    )
    main_param = "f_vv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_vv·v |v| with c_vv = -2309 N s^2/m^2 (95 % CI -2338 to -2281)'
    signature = 'the residual it was fitted to: v |v|'

    @staticmethod
    def piston_force(v, f_vv):
        return -(f_vv * v * abs(v))
