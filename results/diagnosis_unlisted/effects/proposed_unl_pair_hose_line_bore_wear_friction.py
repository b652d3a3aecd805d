"""proposed_unl_pair_hose_line_bore_wear_friction: a term proposed by ehas diagnose for /tmp/drU_work/unl_pair_hose_line+bore_wear_friction/campaign.

F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh) + c_plsv·|p_A - p_B| tanh(v / v_tanh)   with c_x2sv = -4.048e+05 N/m^2 (95 % CI -4.311e+05 to -3.785e+05); c_plsv = 2.13e-05 m^2 (95 % CI 1.522e-05 to 2.738e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 12.7 -> 4.02; fit 82.3 % -> 93.9 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairHoseLineBoreWearFriction(Effect):
    name = "proposed_unl_pair_hose_line_bore_wear_friction"
    title = "proposed term (piston force)"
    params = (
        Param("f_x2sv", "N/m^2", 404831, (0.0, 8.09663e+06),
              "dry force that rises with position squared: per m^2, times sign(v) (fitted: -4.048e+05, 95 % CI -4.311e+05 to -3.785e+05)", typical=(202416, 809663)),
        Param("f_plsv", "m^2", 2.13012e-05, (0.0, 0.000426024),
              "dry force that rises with the load pressure: per Pa of |p_L|, times sign(v) (fitted: 2.13e-05, 95 % CI 1.522e-05 to 2.738e-05)", typical=(1.06506e-05, 4.26024e-05)),
    )
    main_param = "f_x2sv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh) + c_plsv·|p_A - p_B| tanh(v / v_tanh) with c_x2sv = -4.048e+05 N/m^2 (95 % CI -4.311e+05 to -3.785e+05); c_plsv = 2.13e-05 m^2 (95 % CI 1.522e-05 to 2.738e-05)'
    signature = 'the residual it was fitted to: x^2 tanh(v / v_tanh), |p_A - p_B| tanh(v / v_tanh)'

    @staticmethod
    def piston_force(x, v, v_tanh, pa, pb, f_x2sv, f_plsv):
        return -(f_x2sv * x ** 2 * math.tanh(v / v_tanh)) + (f_plsv * abs(pa - pb) * math.tanh(v / v_tanh))
