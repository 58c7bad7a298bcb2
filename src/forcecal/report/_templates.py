"""The reports' Jinja2 templates and their one style sheet, shipped as package data.

``templates/page.html.j2`` is the page every report shares (head, inline style sheet, title,
footer); ``templates/calibration.html.j2`` extends it with the calibration certificate;
``templates/style.css`` is the style sheet of both. The environment autoescapes every value, so
a run, channel or file name can never inject markup, and refuses an undefined name.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from functools import cache
from importlib.resources import files
from typing import Any

import jinja2
from markupsafe import Markup

__all__: list[str] = []

_NUMBER = re.compile(r"[+\-−]?(\d[\d.]*|\.\d+)(e[+\-]?\d+)?( %)?")
"""A cell that is a number (a percentage too): aligned right, in tabular figures."""


def _is_number(value: Any) -> bool:
    return isinstance(value, str) and _NUMBER.fullmatch(value) is not None


@cache
def environment() -> jinja2.Environment:
    """The templates' environment: autoescaped, strict about undefined names.

    Returns
    -------
    jinja2.Environment
    """
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("forcecal.report", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    env.tests["numeric"] = _is_number
    return env


@cache
def style_sheet() -> str:
    """The reports' style sheet (``templates/style.css``).

    Returns
    -------
    str
    """
    return files("forcecal.report").joinpath("templates", "style.css").read_text("utf-8")


def render(template: str, context: Mapping[str, Any]) -> str:
    """A template of the package rendered with ``context`` and the shared style sheet.

    Parameters
    ----------
    template : str
        Its file name under ``templates/``.
    context : mapping
        The template's names (escaped on output unless :class:`markupsafe.Markup`).

    Returns
    -------
    str
        The page.
    """
    return environment().get_template(template).render(
        {**context, "style": Markup(style_sheet())})
