"""proposed_timing_30s_0: a term proposed by ehas diagnose for /tmp/ehas_open_world/timing_30s_0/campaign.

F_piston [N] += c_pb·p_B   with c_pb = -0.0001362 m^2 (95 % CI -0.0001392 to -0.0001332)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 55.2 -> 5.02; fit 12.4 % -> 86.9 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedTiming30s0(Effect):
    name = "proposed_timing_30s_0"
    title = "proposed term (piston force)"
    params = (
        Param("f_pb", "m^2", 0.000136171, (0.0, 0.00272342),
              "force per Pa of chamber B pressure (area error on side B: a single rod) (fitted: -0.0001362, 95 % CI -0.0001392 to -0.0001332)", typical=(6.80855e-05, 0.000272342)),
    )
    main_param = "f_pb"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_pb·p_B with c_pb = -0.0001362 m^2 (95 % CI -0.0001392 to -0.0001332)'
    signature = 'the residual it was fitted to: p_B'

    @staticmethod
    def piston_force(pb, f_pb):
        return -(f_pb * pb)
