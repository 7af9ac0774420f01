"""radio_gateway: bridges Zenoh to the 900 MHz broadcast serial radio with GPS-time TDM.

`core/` is pure (TDM scheduler, framing, fragmentation, authentication); `runtime/`
owns the serial port and the Zenoh session."""
