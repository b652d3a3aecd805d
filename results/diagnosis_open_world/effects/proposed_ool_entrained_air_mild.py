"""proposed_ool_entrained_air_mild: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_entrained_air_mild/campaign.

F_piston [N] += c_pb·p_B   with c_pb = 2.156e-07 m^2 (95 % CI 1.037e-07 to 3.276e-07)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 1.63 -> 1.63; fit 96.3 % -> 96.3 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolEntrainedAirMild(Effect):
    name = "proposed_ool_entrained_air_mild"
    title = "proposed term (piston force)"
    params = (
        Param("f_pb", "m^2", 2.15643e-07, (0.0, 4.31286e-06),
              "force per Pa of chamber B pressure (area error on side B: a single rod) (fitted: 2.156e-07, 95 % CI 1.037e-07 to 3.276e-07)", typical=(1.07821e-07, 4.31286e-07)),
    )
    main_param = "f_pb"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_pb·p_B with c_pb = 2.156e-07 m^2 (95 % CI 1.037e-07 to 3.276e-07)'
    signature = 'the residual it was fitted to: p_B'

    @staticmethod
    def piston_force(pb, f_pb):
        return (f_pb * pb)
