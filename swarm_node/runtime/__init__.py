"""The I/O shell of a vehicle node: Zenoh, MAVLink and SQLite at the edges."""
