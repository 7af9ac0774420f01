"""`gcs map`: the operator's live map in a browser. model.py (pure: the view), server.py
(aiohttp: transport), commands.py (the page's requests, checked and sent as `gcs` does),
replay.py (a flight CSV played back), static/ (the page), command.py (`gcs map`)."""
