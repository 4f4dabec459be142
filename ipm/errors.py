"""Errors a user can cause and fix.  The CLI prints them as one line, without a traceback."""


class UserError(ValueError):
    """Bad input: a file, a value or an option.  The message names the problem."""


class ParamError(UserError):
    """A yarn parameter is missing, of the wrong type, or outside its allowed range."""
