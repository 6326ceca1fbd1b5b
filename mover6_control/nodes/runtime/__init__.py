"""What every node shares: DDS set-up, parameters, the callback guard, clock, QoS, shutdown."""
