"""swarm_sim: MAVLink-speaking simulated vehicles and an emulated radio channel, so a
whole swarm runs on one machine in fast time."""
