"""proposed_ool_valve_direction_gain_mild: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_valve_direction_gain_mild/campaign.

i_valve [mA] += c_abs·|i|   with c_abs = 0.06 - (95 % CI 0.05991 to 0.06008)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 14.1 -> 1.11; fit 92.7 % -> 96.2 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolValveDirectionGainMild(Effect):
    name = "proposed_ool_valve_direction_gain_mild"
    title = "proposed term (valve current)"
    params = (
        Param("i_abs", "-", 0.0599959, (0.0, 1.19992),
              "flow gain change by spool direction: i (1 + c sign(i)) (fitted: 0.06, 95 % CI 0.05991 to 0.06008)", typical=(0.0299979, 0.119992)),
    )
    main_param = "i_abs"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_abs·|i| with c_abs = 0.06 - (95 % CI 0.05991 to 0.06008)'
    signature = 'the residual it was fitted to: |i|'

    @staticmethod
    def valve_current(i, i_abs):
        return i + (i_abs * abs(i))
