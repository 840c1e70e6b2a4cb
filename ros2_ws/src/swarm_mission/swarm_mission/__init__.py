"""Formation shapes, bubble packing and fractal partitioning, and the mission node.

Formation shapes and their partitioning into typed goal states (bubble packing,
randomized fractals), mesh quality metrics, and the mission node.
"""
