"""proposed_ool_lvdt_offset_strong: a term proposed by ehas diagnose for /tmp/ehas_open_world/ool_lvdt_offset_strong/campaign.

i_valve [mA] += c_abs·|i|   with c_abs = 0.0004075 - (95 % CI 0.0002756 to 0.0005394)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 1.43 -> 1.43; fit 96.5 % -> 96.5 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedOolLvdtOffsetStrong(Effect):
    name = "proposed_ool_lvdt_offset_strong"
    title = "proposed term (valve current)"
    params = (
        Param("i_abs", "-", 0.000407507, (0.0, 0.00815014),
              "flow gain change by spool direction: i (1 + c sign(i)) (fitted: 0.0004075, 95 % CI 0.0002756 to 0.0005394)", typical=(0.000203754, 0.000815014)),
    )
    main_param = "i_abs"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_abs·|i| with c_abs = 0.0004075 - (95 % CI 0.0002756 to 0.0005394)'
    signature = 'the residual it was fitted to: |i|'

    @staticmethod
    def valve_current(i, i_abs):
        return i + (i_abs * abs(i))
