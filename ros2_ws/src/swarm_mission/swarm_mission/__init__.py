"""The mission: partitioning a shape into typed goal states and the mission node.

Bubble packing and randomized fractals (thesis 3.2), the goals' mesh quality, beacon
goals, shape generation for studies and the mission node that publishes them; the shape
and goal types it plans on live in swarm_common.
"""
