"""Supply-pressure droop: pump, relief valve and accumulator as a dynamic supply."""
from ehas_env.physics.rig import BAR, LPM
from ehas_env.physics.effects.base import Effect, Param


class SupplyDroop(Effect):
    name = "supply_droop"
    title = "supply pressure droop (pump + accumulator)"
    params = (
        Param("Q_pump", "LPM", 25.0, (0.5, 200.0), "pump flow (book: 25 LPM axial piston pump)", typical=(10.0, 18.0), si=LPM),
        Param("V_acc", "L", 2.5, (0.01, 100.0), "accumulator gas volume at precharge (book: 2.5 L)", typical=(0.5, 2.5), si=1.0e-3),
        Param("p0", "bar", 150.0, (1.0, 219.0), "accumulator precharge pressure (assumed: about 2/3 of the supply)", typical=(120.0, 180.0), si=BAR),
    )
    constants = (
        Param("V_line", "m^3", 0.5e-3, (0.0, 1.0), "pressure line volume between pump and valve (assumed: ~3 m of 1/2\" hose)"),
    )
    main_param = "Q_pump"
    explanation = (
        "The supply is not an ideal pressure source: a pump of limited flow Q_pump (relief at 220 bar) "
        "charges a gas accumulator (isothermal, volume V_acc at precharge p0) and the valve draws from it. "
        "When the valve draws more than the pump delivers, the accumulator discharges and Ps sags, so the "
        "valve passes less flow for the same current."
    )
    signature = (
        "Ps falls below 220 bar during high-demand phases (fast, large motions) and recovers after; the "
        "flow and velocity fall short of the model's at peak demand; the current residual grows with "
        "demand; nothing changes in slow runs."
    )

    @staticmethod
    def supply_rate(ps, q_supply, Q_pump, V_acc, p0, V_line, beta, supply):
        # isothermal gas accumulator plus line volume, fed by the pump, drained by the valve
        cap = V_line / beta
        if ps > p0:
            cap += V_acc * p0 / (ps * ps)
        dps = (Q_pump - q_supply) / cap
        if ps >= supply and dps > 0.0:
            dps = 0.0  # the relief valve holds the setting
        return dps
