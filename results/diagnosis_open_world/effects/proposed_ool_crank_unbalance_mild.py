"""proposed_ool_crank_unbalance_mild: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_crank_unbalance_mild/campaign.

F_piston [N] += c_pb·p_B   with c_pb = -3.508e-05 m^2 (95 % CI -3.6e-05 to -3.415e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 8.16 -> 1.62; fit 80.3 % -> 96.2 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolCrankUnbalanceMild(Effect):
    name = "proposed_ool_crank_unbalance_mild"
    title = "proposed term (piston force)"
    params = (
        Param("f_pb", "m^2", 3.5076e-05, (0.0, 0.00070152),
              "force per Pa of chamber B pressure (area error on side B: a single rod) (fitted: -3.508e-05, 95 % CI -3.6e-05 to -3.415e-05)", typical=(1.7538e-05, 7.0152e-05)),
    )
    main_param = "f_pb"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_pb·p_B with c_pb = -3.508e-05 m^2 (95 % CI -3.6e-05 to -3.415e-05)'
    signature = 'the residual it was fitted to: p_B'

    @staticmethod
    def piston_force(pb, f_pb):
        return -(f_pb * pb)
