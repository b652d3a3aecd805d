"""proposed_d11_piecewise_linear_piston_force: a term proposed by ehas diagnose for /tmp/drawnBw/d11_piecewise_linear@piston_force/campaign.

F_piston [N] += c_vv·v |v| + c_v·v   with c_vv = -2235 N s^2/m^2 (95 % CI -2349 to -2120); c_v = -628.9 N s/m (95 % CI -702.6 to -555.2)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 7.88 -> 1.38; fit 86.6 % -> 96.2 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD11PiecewiseLinearPistonForce(Effect):
    name = "proposed_d11_piecewise_linear_piston_force"
    title = "proposed term (piston force)"
    params = (
        Param("f_vv", "N s^2/m^2", 2234.71, (0.0, 44694.1),
              "quadratic damping: force per (m/s)^2, signed (fitted: -2235, 95 % CI -2349 to -2120)", typical=(1117.35, 4469.41)),
        Param("f_v", "N s/m", 628.896, (0.0, 12577.9),
              "viscous force per m/s (fitted: -628.9, 95 % CI -702.6 to -555.2)", typical=(314.448, 1257.79)),
    )
    main_param = "f_vv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_vv·v |v| + c_v·v with c_vv = -2235 N s^2/m^2 (95 % CI -2349 to -2120); c_v = -628.9 N s/m (95 % CI -702.6 to -555.2)'
    signature = 'the residual it was fitted to: v |v|, v'

    @staticmethod
    def piston_force(v, f_vv, f_v):
        return -(f_vv * v * abs(v)) + -(f_v * v)
