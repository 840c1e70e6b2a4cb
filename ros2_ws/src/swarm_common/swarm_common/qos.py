"""Named QoS profiles shared by every swarm node, as plain keyword arguments.

Nodes build them with ``rclpy.qos.QoSProfile(**PROFILE)``. The integers are the values
of rclpy's ``QoSHistoryPolicy``, ``QoSReliabilityPolicy`` and ``QoSDurabilityPolicy``
enums (checked by a unit test), kept here so that this module stays free of rclpy.
"""

KEEP_LAST = 1
RELIABLE = 1
BEST_EFFORT = 2
TRANSIENT_LOCAL = 1
VOLATILE = 2

# Shapes and goals: late joiners get the latest version (latched, as in navigation2).
LATCHED = {'history': KEEP_LAST, 'depth': 1, 'reliability': RELIABLE,
           'durability': TRANSIENT_LOCAL}
# High-rate sensor data and commands: the newest sample matters, old ones are useless.
SENSOR = {'history': KEEP_LAST, 'depth': 5, 'reliability': BEST_EFFORT,
          'durability': VOLATILE}
# Force commands: the latest command is the robot's state, so a simulator that matches
# an agent late must still get it. With SENSOR (volatile), a first command published
# before discovery had matched the simulator was lost, and the simulator, holding its
# clock for the agent's first command, kept the agent's timers from firing again: 15 of
# 50 composed agents unheard until the 60 s start-up window ran out (measured).
COMMAND = {'history': KEEP_LAST, 'depth': 1, 'reliability': RELIABLE,
           'durability': TRANSIENT_LOCAL}
# Batches of many agents' commands (swarm_msgs/ForceBatch): each holds only the agents
# whose command changed, so none may be dropped; kept for a late-matching simulator too.
COMMAND_BATCH = {'history': KEEP_LAST, 'depth': 100, 'reliability': RELIABLE,
                 'durability': TRANSIENT_LOCAL}
# Accelerometer samples: each carries the mean acceleration of its interval, so a
# dropped sample is a lost velocity increment for the Kalman filter: reliable, deep.
IMU = {'history': KEEP_LAST, 'depth': 50, 'reliability': RELIABLE,
       'durability': VOLATILE}
# Radio frames: the medium model decides what is lost, DDS must not add losses.
RADIO = {'history': KEEP_LAST, 'depth': 1000, 'reliability': RELIABLE,
         'durability': VOLATILE}
# Introspection (state, routes, truth): reliable, shallow.
STATE = {'history': KEEP_LAST, 'depth': 10, 'reliability': RELIABLE,
         'durability': VOLATILE}
