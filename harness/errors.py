"""Errors that reach the user as one clear line and a non-zero exit (no traceback)."""


class UserError(Exception):
    """Bad input or configuration; the message names the culprit."""
