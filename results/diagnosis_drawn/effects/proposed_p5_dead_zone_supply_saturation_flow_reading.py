"""proposed_p5_dead_zone_supply_saturation_flow_reading: a term proposed by ehas diagnose for /tmp/drawnBw/p5_dead_zone@supply+saturation@flow_reading/campaign.

(Q_A, Q_B) [m^3/s] += c_rsup2·the inflow land's flow times -q_S^2 / (2 (p_S - p_in)): supply drop per supply flow squared   with c_rsup2 = 4.117e+12 Pa s^2/m^6 (95 % CI 4.066e+12 to 4.167e+12)

Residual (geometric mean of noise-normalised residual energy, 1 = noise): 3.52 -> 1.54; fit 93.6 % -> 96.0 %.
Rename the file, the class and ``name``, give the parameters physical names and documentation,
then: ehas compare CAMPAIGN --effects-path DIR --effects NAME --fit
"""
from ehas_env.physics.effects import Effect, Param


class ProposedP5DeadZoneSupplySaturationFlowReading(Effect):
    name = "proposed_p5_dead_zone_supply_saturation_flow_reading"
    title = "proposed term (chamber flows)"
    params = (
        Param("q_rsup2", "Pa s^2/m^6", 4.11664e+12, (0.0, 8.23328e+13),
              "turbulent supply drop: supply pressure drop per supply flow squared (fitted: 4.117e+12, 95 % CI 4.066e+12 to 4.167e+12)", typical=(2.05832e+12, 8.23328e+12)),
    )
    main_param = "q_rsup2"
    valve_side = True
    explanation = "Proposed by the diagnosis, not yet a physical explanation: (Q_A, Q_B) [m^3/s] += c_rsup2·the inflow land's flow times -q_S^2 / (2 (p_S - p_in)): supply drop per supply flow squared with c_rsup2 = 4.117e+12 Pa s^2/m^6 (95 % CI 4.066e+12 to 4.167e+12)"
    signature = "the residual it was fitted to: the inflow land's flow times -q_S^2 / (2 (p_S - p_in)): supply drop per supply flow squared"

    @staticmethod
    def chamber_flows(pa, pb, ps, q_a, q_b, qc, q_supply, q_rsup2):
        dqa = 0.0
        dqb = 0.0
        if qc >= 0.0:
            dqa -= q_rsup2 * q_supply ** 2 * q_a / (2.0 * max(ps - pa, 1.0e5))
        else:
            dqb -= q_rsup2 * q_supply ** 2 * q_b / (2.0 * max(ps - pb, 1.0e5))
        return dqa, dqb
