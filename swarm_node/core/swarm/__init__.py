"""Swarm manager cores (paper section 2.3.3): who is in a mission's fleet."""
