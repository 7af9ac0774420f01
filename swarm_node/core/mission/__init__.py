"""Mission manager cores (paper section 2.3.5)."""
