"""Pure decision logic of a vehicle node. Nothing here imports zenoh, serial, asyncio,
socket or time (tests/test_architecture.py enforces it): inputs and `now` go in,
actions come out."""
