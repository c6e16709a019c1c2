"""The command line's wording of the library's messages: ``--model voronets``, not ``model='voronets'``.

The library's errors and warnings name what to pass in Python syntax (``model='voronets'``,
``time_limit=None``, ``resume=True``), which is right for the Python API and wrong on the command
line.  :func:`cli_wording` rewrites each such hint into the option that does the same
(``--model voronets``, ``--time-limit 0``, ``--resume``); the command line passes every message
it prints through it (``error:``, ``warning:``, ``stopped early:`` lines, and ``check``'s text).
A hint in parentheses that begins with ``or`` and names a keyword the command line lacks
(``(or the initial multipliers, multipliers=[...])``) is dropped, since it cannot be followed there.
"""

from __future__ import annotations

import re

__all__ = ["CLI_OPTIONS", "CLI_PHRASES", "PYTHON_HINT", "cli_wording"]

#: a Python keyword of the API → the option of the command line that gives it
CLI_OPTIONS = {
    "model": "--model",
    "models": "--models",
    "form": "--form",
    "constants": "--constants",
    "backend": "--backend",
    "method": "--method",
    "step": "--step",
    "time_limit": "--time-limit",
    "t_end": "--t-end",
    "samples": "--samples",
    "rtol": "--rtol",
    "atol": "--atol",
    "parameters": "--param",
    "initial": "--initial",
    "grid": "--grid",
    "resume": "--resume",
    "force": "--force",
    "workers": "--workers",
    "chunk_size": "--chunk-size",
    "out": "--out",
    "scheduler": "--scheduler",
    "to": "--to",
    "prefix": "--prefix",
}
#: a phrase of the API's messages → the option of the command line it names (the command
#: line's runs start at t = 0: its end time is the whole span)
CLI_PHRASES = {"t_span: the end time": "--t-end"}
#: keywords of the API that the command line has no option for
PYTHON_ONLY = ("multipliers", "threads", "keep", "path", "what", "max_step")

_VALUE = r"'[^']*'|\"[^\"]*\"|\[[^\]]*\]|None|True|False|\.\.\.|[-+]?(?:\d|\.\d)[\w.+-]*"
#: a Python keyword hint: ``model='voronets'``, ``time_limit=None``, ``resume=True``, ``t_end = 5``
#: (also the bare ``parameters=``): what :func:`cli_wording` rewrites, and what a command line
#: message must not contain
PYTHON_HINT = re.compile(rf"(?<![\w.\-'\"])(?P<key>[A-Za-z_]\w*)(?: = |=)(?P<value>{_VALUE})?(?![\w=])")
_DROPPED = re.compile(rf"\s*\(or [^()]*\b(?:{'|'.join(PYTHON_ONLY)})=[^()]*\)")


def _option(match: re.Match[str]) -> str:
    key, value = match["key"], match["value"]
    option = CLI_OPTIONS.get(key)
    if option is None:
        return match[0]
    if value is None or value == "True":  # a flag (--resume), or a bare option (--param)
        return option
    if value == "None" and key == "time_limit":
        return f"{option} 0"
    if value[0] in "'\"":
        value = value[1:-1]
    elif value[0] == "[":  # ['chetaev', 'vakonomic'] -> chetaev,vakonomic
        value = ",".join(v.strip().strip("'\"") for v in value[1:-1].split(","))
    return f"{option} {value}"


def cli_wording(text: str) -> str:
    """``text`` with each Python keyword hint of the API written as its command-line option.

    Examples
    --------
    >>> cli_wording("does not apply. Use model='voronets', which allows T, U and B")
    'does not apply. Use --model voronets, which allows T, U and B'
    >>> cli_wording("pass time_limit=None with resume=True to finish")
    'pass --time-limit 0 with --resume to finish'
    >>> cli_wording("t_span: the end time -1 must be after the start 0.")
    '--t-end -1 must be after the start 0.'
    """
    for python, option in CLI_PHRASES.items():
        text = text.replace(python, option)
    return PYTHON_HINT.sub(_option, _DROPPED.sub("", text))
