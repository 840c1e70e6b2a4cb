"""pybullet world, sensors and radio medium of the swarm, and the sim node.

pybullet replacement of the thesis Gazebo world: rough terrain, obstacles, heterogeneous
robots, noisy sensors and the radio medium, behind the sim node.
"""
