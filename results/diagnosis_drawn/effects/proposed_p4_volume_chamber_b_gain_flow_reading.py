"""proposed_p4_volume_chamber_b_gain_flow_reading: a term proposed by ehas diagnose for /tmp/drD2_work/p4_volume@chamber_b+gain@flow_reading/campaign.

F_piston [N] += c_vv·v |v|   with c_vv = -880.7 N s^2/m^2 (95 % CI -915 to -846.4)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 4.29 -> 3.59; fit 86.4 % -> 86.1 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP4VolumeChamberBGainFlowReading(Effect):
    name = "proposed_p4_volume_chamber_b_gain_flow_reading"
    title = "proposed term (piston force)"
    params = (
        Param("f_vv", "N s^2/m^2", 880.691, (0.0, 17613.8),
              "quadratic damping: force per (m/s)^2, signed (fitted: -880.7, 95 % CI -915 to -846.4)", typical=(440.346, 1761.38)),
    )
    main_param = "f_vv"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: F_piston [N] += c_vv·v |v| with c_vv = -880.7 N s^2/m^2 (95 % CI -915 to -846.4)'
    signature = 'the residual it was fitted to: v |v|'

    @staticmethod
    def piston_force(v, f_vv):
        return -(f_vv * v * abs(v))
