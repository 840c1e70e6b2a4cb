"""Robot types of thesis Table 4.1: re-exported from ``swarm_mission.robot_types``.

The table lives in swarm_mission (the lowest Python layer, which the agents, the
simulator and the mission node all depend on); import it from there.
"""

from swarm_mission.robot_types import *  # noqa: F401,F403
from swarm_mission.robot_types import DEFAULT_CONFIG, GRAVITY, LqrDesign, RobotType, RobotTypeError  # noqa: F401
