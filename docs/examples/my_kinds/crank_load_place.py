"""A place of my own: the crank's torque balance with the load pressure (a bearing's friction that rises with the
load it carries, acting at the crank, not at the piston), every built-in kind of static term put there."""
from ehas_env.physics.balance_blocks import BALANCE_KINDS, BalancePlace

CRANK_LOAD = BalancePlace("crank_torque", "crank_load", "p_load", "Pa", 1.0e7, (1.0e-5, "bar"), "N m", 250.0,
                          (1.0, "N m"), "t", "the crank torque balance", "the load pressure p_A - p_B")
TERMS = [kind.at(CRANK_LOAD) for kind in BALANCE_KINDS if kind.fits(CRANK_LOAD)]
