"""The designers' linear plant, for the controllers' users: :mod:`ehas_env.simulation.linear_model`.

It lives in the simulation layer (the identification's curves use it too, and a lower layer may not import this
package); this name keeps ``ehas_controllers.linear_model.LinearPlant`` working.
"""
from ehas_env.simulation.linear_model import LinearPlant, operating_flow_lpm

__all__ = ["LinearPlant", "operating_flow_lpm"]
