"""Supply-pressure droop: pump, relief valve and accumulator as a dynamic supply."""
from ehas_env.physics.rig import BAR, LPM
from ehas_env.physics.effects.base import Effect, Param


class SupplyDroop(Effect):
    name = "supply_droop"
    title = "supply pressure droop (pump + accumulator)"
    params = (
        Param("Q_pump", "LPM", 25.0, (0.5, 200.0), "pump flow (book: 25 LPM axial piston pump)", typical=(10.0, 18.0)),
        Param("V_acc", "L", 2.5, (0.01, 100.0), "accumulator gas volume at precharge (book: 2.5 L)", typical=(0.5, 2.5)),
        Param("p0", "bar", 150.0, (1.0, 219.0), "accumulator precharge pressure (assumed: about 2/3 of the supply)", typical=(120.0, 180.0)),
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

    @classmethod
    def apply(cls, values, slots):
        slots["droop"] = 1.0
        slots["Q_pump"] = values["Q_pump"] * LPM
        slots["V_acc"] = values["V_acc"] * 1.0e-3
        slots["p0"] = values["p0"] * BAR
