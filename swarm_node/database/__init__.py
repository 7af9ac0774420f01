"""The swarm database (paper section 2.3.1): an embedded SQLite file on every vehicle,
ground station and simulator, served to peers over a Zenoh queryable.

    from swarm_node.database import SwarmDatabase

    db = SwarmDatabase.open(path)                # or SwarmDatabase.memory()
    me = db.vehicle_profile(vehicle_id=3)        # -> swarm_node.core.profile.VehicleProfile
    me = db.vehicle_profile(user_id="ALB-03", model="Albatross 250 VTOL")
    fleet = db.profiles()                        # every system
    db.payload_class("EO 12 Mpx 3-axis gimbal")  # -> PayloadClass(type, subtype, model)

For tests: `seed_profiles()["Albatross 250 VTOL"]` (built once per process). Records,
export/import and errors: see `repository.py`; the Zenoh side: `queryable.py`;
the layout: docs/database.md.
"""

from .errors import (
    AmbiguousError,
    ConstraintError,
    CorruptDatabaseError,
    DocumentError,
    DuplicateError,
    ForeignDatabaseError,
    InterruptedWriteError,
    InUseError,
    InvalidValueError,
    NewerSchemaError,
    NotFoundError,
    ProfileError,
    RecordError,
    StorageError,
    SwarmDbError,
    UnknownReferenceError,
    UnknownTableError,
    UnusableDatabaseError,
)
from .paths import ENV_VAR, default_db_path, resolve_db_path
from .repository import (
    SwarmDatabase,
    inspect_file,
    seed_fleet,
    seed_payload_classes,
    seed_profiles,
)
from .schema import APPLICATION_ID, LATEST_VERSION
from .seed import ALBATROSS, BOAT, GCS_NODE_ID, GROUND_STATION, QUADCOPTER, ROVER, SEED_MODELS

__all__ = [
    "ALBATROSS",
    "APPLICATION_ID",
    "BOAT",
    "ENV_VAR",
    "GCS_NODE_ID",
    "GROUND_STATION",
    "LATEST_VERSION",
    "QUADCOPTER",
    "ROVER",
    "SEED_MODELS",
    "AmbiguousError",
    "ConstraintError",
    "CorruptDatabaseError",
    "DocumentError",
    "DuplicateError",
    "ForeignDatabaseError",
    "InUseError",
    "InterruptedWriteError",
    "InvalidValueError",
    "NewerSchemaError",
    "NotFoundError",
    "ProfileError",
    "RecordError",
    "StorageError",
    "SwarmDatabase",
    "SwarmDbError",
    "UnknownReferenceError",
    "UnknownTableError",
    "UnusableDatabaseError",
    "default_db_path",
    "inspect_file",
    "resolve_db_path",
    "seed_fleet",
    "seed_payload_classes",
    "seed_profiles",
]
