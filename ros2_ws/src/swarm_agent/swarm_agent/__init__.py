"""Robot brain of the swarm (DSDV, localization, assignment, LQR) and the agent node.

The robot brain of the swarm: DSDV mesh routing, trilateration and Kalman localization,
lost/return-home modes, goal costs, Hungarian assignment consensus, artificial forces
and the LQR velocity loop, behind a thin agent node.
"""
