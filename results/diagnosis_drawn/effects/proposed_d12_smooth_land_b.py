"""proposed_d12_smooth_land_b: a term proposed by ehas diagnose for /tmp/drawnAw/d12_smooth@land_b/campaign.

i_valve [mA] += c_i3·i^3   with c_i3 = 0.0001745 1/mA^2 (95 % CI 0.0001719 to 0.0001772)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 3.04 -> 1.82; fit 95.5 % -> 95.7 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedD12SmoothLandB(Effect):
    name = "proposed_d12_smooth_land_b"
    title = "proposed term (valve current)"
    params = (
        Param("i_i3", "1/mA^2", 0.000174546, (0.0, 0.00349092),
              "cubic current: a gain that falls (c < 0, saturation) or rises with |i| (fitted: 0.0001745, 95 % CI 0.0001719 to 0.0001772)", typical=(8.7273e-05, 0.000349092)),
    )
    main_param = "i_i3"
    explanation = 'Proposed by the diagnosis, not yet a physical explanation: i_valve [mA] += c_i3·i^3 with c_i3 = 0.0001745 1/mA^2 (95 % CI 0.0001719 to 0.0001772)'
    signature = 'the residual it was fitted to: i^3'

    @staticmethod
    def valve_current(i, i_i3):
        return i + (i_i3 * i ** 3)
