"""The emulated 900 MHz XTend channel: a pure model of modules on one broadcast channel
(`model`), a fleet harness of radio node cores in simulated time (`harness`), and N
pseudo-terminal endpoints for real gateways (`pty`)."""
