"""Test plant: the disc stack on the shaft through a friction-limited coupling that slips at high torque."""
import math

from ehas_env.physics.effects.base import Effect, Param


class SlipCoupling(Effect):
    name = "slip_coupling"
    title = "disc stack on the shaft through a coupling that slips at high torque (test plant)"
    kind = "hypothesis"  # a plant built to break the learning controllers, not a diagnosis candidate
    params = (
        Param("T_slip", "N m", 350.0, (1.0, 1.0e5), "torque at which the coupling slips (Dahl friction level)"),
        Param("I_discs", "kg m^2", 2.681, (0.01, 100.0), "inertia of the disc stack behind the coupling"),
        Param("k_c", "N m/rad", 5.0e4, (1.0e2, 1.0e7), "torsional stiffness of the coupling while it sticks"),
        Param("c_c", "N m s/rad", 30.0, (0.0, 1.0e4), "damping across the coupling"),
    )
    constants = (Param("rate_max", "1/s", 2000.0, (1.0, 1e6), "fastest relaxation of the deflection the "
                                                                 "integrator resolves"),)
    main_param = "T_slip"
    states = (("w_d", "rad/s", 0.0), ("z", "rad", 0.0))
    explanation = (
        "The crank carries only its hub (the plant's inertia); the disc stack I_discs sits behind a coupling of "
        "stiffness k_c whose deflection z follows the Dahl friction law z' = dw - k_c |dw| z / T_slip "
        "(dw = crank speed - disc speed): below T_slip it is a stiff spring, near it the stack slips."
    )
    signature = "the load torque saturates at T_slip at the peaks of acceleration; the stack lags the shaft"

    @staticmethod
    def state_rates(omega, w_d, z, T_slip, I_discs, k_c, c_c, rate_max):
        dw = omega - w_d
        k = k_c * abs(dw) / T_slip
        if k <= rate_max:
            dz = dw - k * z
        else:  # sliding faster than the integrator resolves: relax to the slipping deflection at the resolved rate
            dz = rate_max * (math.copysign(T_slip / k_c, dw) - z)
        torque = k_c * z + c_c * dz
        return (torque / I_discs, dz)

    @staticmethod
    def crank_torque(omega, w_d, z, T_slip, k_c, c_c, rate_max):
        dw = omega - w_d
        k = k_c * abs(dw) / T_slip
        if k <= rate_max:
            dz = dw - k * z
        else:
            dz = rate_max * (math.copysign(T_slip / k_c, dw) - z)
        return -(k_c * z + c_c * dz)
