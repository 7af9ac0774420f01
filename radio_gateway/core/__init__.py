"""Pure radio protocol logic: bytes, messages and `now` in, actions out."""
