"""proposed_unl_pair_hose_line_bore_wear_friction: a term proposed by ehas diagnose for /tmp/unlL_work/unl_pair_hose_line+bore_wear_friction/campaign.

F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh)   with c_x2sv = -2.947e+05 N/m^2 (95 % CI -2.999e+05 to -2.895e+05)
i_valve [mA] += c_i3·i^3   with c_i3 = -0.0001327 1/mA^2 (95 % CI -0.0001379 to -0.0001275)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 22.4 -> 10.7; fit 81.2 % -> 83.8 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
import math

from ehas_env.physics.effects import Effect, Param


class ProposedUnlPairHoseLineBoreWearFriction(Effect):
    name = "proposed_unl_pair_hose_line_bore_wear_friction"
    title = "proposed term (piston force, valve current)"
    params = (
        Param("f_x2sv", "N/m^2", 294686, (0.0, 5.89371e+06),
              "dry force that rises with position squared: per m^2, times sign(v) (fitted: -2.947e+05, 95 % CI -2.999e+05 to -2.895e+05)", typical=(147343, 589371)),
        Param("i_i3", "1/mA^2", 0.000132712, (0.0, 0.00265425),
              "cubic current: a gain that falls (c < 0, saturation) or rises with |i| (fitted: -0.0001327, 95 % CI -0.0001379 to -0.0001275)", typical=(6.63562e-05, 0.000265425)),
    )
    main_param = "f_x2sv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_x2sv·x^2 tanh(v / v_tanh) with c_x2sv = -2.947e+05 N/m^2 (95 % CI -2.999e+05 to -2.895e+05); i_valve [mA] += c_i3·i^3 with c_i3 = -0.0001327 1/mA^2 (95 % CI -0.0001379 to -0.0001275)'
    signature = 'the residual it was fitted to: i^3, x^2 tanh(v / v_tanh)'

    @staticmethod
    def piston_force(x, v, v_tanh, f_x2sv):
        return -(f_x2sv * x ** 2 * math.tanh(v / v_tanh))

    @staticmethod
    def valve_current(i, i_i3):
        return i + -(i_i3 * i ** 3)
