"""External leakage from each chamber to drain."""
from ehas_env.physics.effects.base import Effect, Param


class ExternalLeakage(Effect):
    name = "external_leakage"
    title = "external leakage from the chambers to drain"
    params = (
        Param("C_ext", "m^3/s/Pa", 5.0e-13, (0.0, 1.0e-10),
              "laminar leakage coefficient of each chamber to drain (rod seal, fittings; assumed)",
              typical=(2.0e-13, 2.0e-12), log_scale=True),
    )
    main_param = "C_ext"
    explanation = (
        "Rod seals and fittings let oil escape from each chamber to drain, C_ext P_A and C_ext P_B. Unlike "
        "internal leakage it drains both chambers at once, so it lowers the mean chamber pressure and the "
        "valve must keep refilling both sides."
    )
    signature = (
        "mean chamber pressure (P_A + P_B)/2 falls below the model's; flow in line A exceeds A x' by "
        "C_ext P_A even at rest; a constant current offset when holding."
    )

    @staticmethod
    def chamber_flows(pa, pb, C_ext):
        return -(C_ext * pa), -(C_ext * pb)
