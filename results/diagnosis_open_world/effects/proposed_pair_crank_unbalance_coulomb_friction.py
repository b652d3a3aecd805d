"""proposed_pair_crank_unbalance_coulomb_friction: a term proposed by ehas diagnose for /tmp/ehas_open_world/pair_crank_unbalance+coulomb_friction/campaign.

F_piston [N] += c_pb·p_B   with c_pb = -4.022e-05 m^2 (95 % CI -4.123e-05 to -3.921e-05)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 11.2 -> 1.85; fit 68.6 % -> 94.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedPairCrankUnbalanceCoulombFriction(Effect):
    name = "proposed_pair_crank_unbalance_coulomb_friction"
    title = "proposed term (piston force)"
    params = (
        Param("f_pb", "m^2", 4.02171e-05, (0.0, 0.000804342),
              "force per Pa of chamber B pressure (area error on side B: a single rod) (fitted: -4.022e-05, 95 % CI -4.123e-05 to -3.921e-05)", typical=(2.01085e-05, 8.04342e-05)),
    )
    main_param = "f_pb"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_pb·p_B with c_pb = -4.022e-05 m^2 (95 % CI -4.123e-05 to -3.921e-05)'
    signature = 'the residual it was fitted to: p_B'

    @staticmethod
    def piston_force(pb, f_pb):
        return -(f_pb * pb)
