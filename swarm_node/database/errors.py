"""Errors of the swarm database, by blame.

`UnusableDatabaseError`: the file cannot be used (corrupt, another application's, a
newer schema, or unreadable/unwritable: `StorageError`); the file is left exactly as
it was. `RecordError`: a record given to the
database (by the operator, an import file, our own code) breaks a rule; nothing is
written. Every message names the table, the record and the rule, for an operator.
"""

from __future__ import annotations

import reprlib
from typing import Any

_repr = reprlib.Repr()
_repr.maxlevel = 3
_repr.maxstring = 80
_repr.maxother = 80


def shown(value: Any) -> str:
    """A value for an error message: its repr, shortened (an operator's input can be
    a megabyte string or a list nested thousands deep, whose plain repr would fail)."""
    return _repr.repr(value)


class SwarmDbError(Exception):
    """Base class of every error raised by swarm_node.database."""


class UnusableDatabaseError(SwarmDbError):
    """The database file cannot be used; it was not modified."""


class CorruptDatabaseError(UnusableDatabaseError):
    """Not an SQLite file, or a damaged one."""


class ForeignDatabaseError(UnusableDatabaseError):
    """An SQLite file that is not a bandada swarm database."""


class NewerSchemaError(UnusableDatabaseError):
    """A bandada swarm database written by a newer bandada (a schema we do not know)."""


class StorageError(UnusableDatabaseError):
    """The file or its directory cannot be read or written (permission denied, a
    read-only filesystem, a disk full, a lock held too long by another process); what
    was being written was rolled back."""


class InterruptedWriteError(UnusableDatabaseError):
    """A bandada database whose last write was interrupted (a hot journal beside it);
    `SwarmDatabase.open` rolls it back to the last committed state."""


class RecordError(SwarmDbError, ValueError):
    """A record breaks a rule of the database; nothing was written."""


class UnknownTableError(RecordError):
    """No such group or table."""


class InvalidValueError(RecordError):
    """A field is unknown, missing, or has a value of the wrong type or out of range."""


class UnknownReferenceError(RecordError):
    """A field names a record that does not exist (an unknown model, layout, ...)."""


class DuplicateError(RecordError):
    """A record with the same unique key exists (model name, user id + layout, ...)."""


class NotFoundError(RecordError):
    """No record has the given key."""


class AmbiguousError(RecordError):
    """The given key matches several records."""


class InUseError(RecordError):
    """The record is referenced by other records and cannot be removed."""


class ConstraintError(RecordError):
    """A value breaks a rule (a CHECK or a trigger) of the schema."""


class DocumentError(RecordError):
    """An export document (JSON) is malformed or of an unknown format or version."""


class ProfileError(SwarmDbError, LookupError):
    """A node's identity or planning parameters cannot be resolved."""
