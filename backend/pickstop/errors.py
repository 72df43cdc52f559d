"""Typed errors. Every failure PickStop reports derives from :class:`PickStopError`.

Only the edges translate them: the CLI into exit codes, the API into problem details.
"""

from __future__ import annotations


class PickStopError(Exception):
    """Root of every error PickStop raises on purpose."""

    #: Exit code the CLI uses for this error.
    exit_code = 1

    def __init__(self, message: str, *, field: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        #: The offending input field, dotted (``"arm_joints[2]"``), when one is to blame.
        self.field = field


class InputError(PickStopError):
    """The caller gave something invalid (a bad argument, file or value)."""

    exit_code = 2


class ExistsError(InputError):
    """What a request would create exists already (a robot of that name)."""


class RobotConfigError(InputError):
    """A robot config, URDF, SRDF or mesh cannot be used."""


class DatabaseError(PickStopError):
    """A reachability database cannot be built, found or trusted."""


class DatabaseNotFoundError(DatabaseError):
    """No complete database matches the request (the message names the command that builds
    it)."""

    exit_code = 5


class DatabaseMismatchError(DatabaseError):
    """A database was built for another robot or robot config than the one given."""

    exit_code = 2  # the database named does not fit the robot named: bad input


class DatabaseBusyError(DatabaseError):
    """A database is being built: it cannot be used or deleted now."""


class CorruptShardError(DatabaseError):
    """A shard file is missing, truncated or does not match its recorded checksum."""


class QueryError(InputError):
    """A pose query is malformed (shape, NaN, non-unit quaternion)."""


class UnavailableError(PickStopError):
    """The work could not be done now, through no fault of the request: try again."""


def dump_error(e: BaseException) -> bytes:
    """``e`` pickled to cross to another process (the planner's, the API's), or a
    :class:`PickStopError` with its message and field if it will not."""
    import pickle

    try:
        data = pickle.dumps(e)
        pickle.loads(data)
        return data
    except Exception:
        msg = getattr(e, "message", None) or f"{type(e).__name__}: {e}"
        return pickle.dumps(PickStopError(str(msg), field=getattr(e, "field", None)))


def load_error(
    payload: bytes, failed: type[Exception] = UnavailableError, words: str = ""
) -> BaseException:
    """The exception :func:`dump_error` sent; a ``failed`` with ``words`` if it cannot be
    rebuilt in this process (or with what came, if that is no exception)."""
    import pickle

    try:
        err = pickle.loads(payload)
    except Exception:  # a class this process cannot rebuild: keep the words
        return failed(words or "an error could not be passed on from another process")
    return err if isinstance(err, BaseException) else failed(str(err))
