"""proposed_d11_piecewise_linear_piston_force: a term proposed by ehas diagnose for /tmp/dr2_work/d11_piecewise_linear@piston_force/campaign.

F_piston [N] += c_v·v   with c_v = -1079 N s/m (95 % CI -1089 to -1069)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 2.43 -> 1.22; fit 92.6 % -> 96.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD11PiecewiseLinearPistonForce(Effect):
    name = "proposed_d11_piecewise_linear_piston_force"
    title = "proposed term (piston force)"
    params = (
        Param("f_v", "N s/m", 1079.11, (0.0, 21582.1),
              "viscous force per m/s (fitted: -1079, 95 % CI -1089 to -1069)", typical=(539.553, 2158.21)),
    )
    main_param = "f_v"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_v·v with c_v = -1079 N s/m (95 % CI -1089 to -1069)'
    signature = 'the residual it was fitted to: v'

    @staticmethod
    def piston_force(v, f_v):
        return -(f_v * v)
