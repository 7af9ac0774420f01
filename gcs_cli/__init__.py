"""gcs_cli: the Typer ground station (fleet status and every operator command)."""
