"""Errors that reach the user as one clear line and exit status 2 (no traceback)."""


class UserError(Exception):
    """Bad input or configuration; the message names the culprit."""


class FrameError(UserError, ValueError):
    """A frame or predictions file is missing or malformed.  The message names the file."""
