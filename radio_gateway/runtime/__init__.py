"""Serial port and Zenoh shell of the radio gateway."""
