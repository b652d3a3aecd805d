"""proposed_ool_single_rod_mild: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_single_rod_mild/campaign.

F_piston [N] += c_pb·p_B   with c_pb = 7.965e-05 m^2 (95 % CI 7.845e-05 to 8.086e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 51.8 -> 20.3; fit 43.5 % -> 70.3 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolSingleRodMild(Effect):
    name = "proposed_ool_single_rod_mild"
    title = "proposed term (piston force)"
    params = (
        Param("f_pb", "m^2", 7.96539e-05, (0.0, 0.00159308),
              "force per Pa of chamber B pressure (area error on side B: a single rod) (fitted: 7.965e-05, 95 % CI 7.845e-05 to 8.086e-05)", typical=(3.98269e-05, 0.000159308)),
    )
    main_param = "f_pb"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_pb·p_B with c_pb = 7.965e-05 m^2 (95 % CI 7.845e-05 to 8.086e-05)'
    signature = 'the residual it was fitted to: p_B'

    @staticmethod
    def piston_force(pb, f_pb):
        return (f_pb * pb)
