"""Safety cores: closest-approach geometry (`ttc`) and collision avoidance (`avoidance`)."""
