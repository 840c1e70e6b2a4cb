"""What every swarm package shares: robot types, fleets, shapes and goals, QoS profiles,
message conversions of shapes and goals, shared-memory hygiene and node helpers."""
