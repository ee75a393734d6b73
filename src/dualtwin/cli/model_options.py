"""Command options derived from a pydantic model, so a config's field list is written once.

:func:`model_options` turns every field of a model into a typer option of the decorated command: the field's
description is the option's ``--help``, ``Literal`` fields list their choices (an ``Enum``, so ``--help``
shows them and typos are usage errors), lists are repeatable options, and mappings and nested models are
repeatable ``KEY=VALUE`` options (``KEY=LOW,HIGH`` for a pair). The command receives the given values as
``fields`` (only options the user gave, so the model's defaults stay the model's) and validates them with
:func:`validate_model`, whose errors name the option.

Field metadata (``json_schema_extra``): ``derived`` (filled in by the program, no option), ``cli`` (the
option's name when it differs from the field's, e.g. the suite is ``--scenarios`` in every command) and
``path`` (the option takes a path, so the CLI's path policies apply to it).
"""

from __future__ import annotations

import enum
import inspect
import types
import typing
from collections.abc import Callable, Collection
from pathlib import Path
from typing import Annotated, Any, Literal

import typer
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from dualtwin.errors import DualtwinError

#: How a field's value arrives on the command line.
Shape = Literal["scalar", "choice", "list", "mapping", "pairs", "model"]


def _extra(field: FieldInfo) -> dict[str, Any]:
    return field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}


def option_name(name: str, field: FieldInfo) -> str:
    """The command-line name (without ``--``, underscores as dashes) of a field."""
    return str(_extra(field).get("cli", name)).replace("_", "-")


def cli_fields(model: type[BaseModel]) -> dict[str, FieldInfo]:
    """The fields that become options (every field not marked ``derived``)."""
    return {n: f for n, f in model.model_fields.items() if not _extra(f).get("derived")}


def _strip_optional(annotation: Any) -> tuple[Any, bool]:
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(args) == 1:
            return args[0], True
    return annotation, False


def _shape(annotation: Any) -> tuple[Shape, Any]:
    """The field's shape and its item type (the choices for ``choice``)."""
    origin = typing.get_origin(annotation)
    if origin is Literal:
        return "choice", typing.get_args(annotation)
    if origin is list:
        return "list", typing.get_args(annotation)[0]
    if origin is dict:
        value = typing.get_args(annotation)[1]
        return ("pairs", value) if typing.get_origin(value) is tuple else ("mapping", value)
    if inspect.isclass(annotation) and issubclass(annotation, BaseModel):
        return "model", annotation
    return "scalar", annotation


def _choices(name: str, values: tuple[Any, ...]) -> type[enum.Enum]:
    members = {str(v): str(v) for v in values}
    return enum.Enum(name.title().replace("_", ""), members, type=str)  # type: ignore[return-value]


def _option(name: str, field: FieldInfo, optional: bool,
            choices: Collection[str] | None = None) -> tuple[inspect.Parameter, Shape]:
    annotation, _ = _strip_optional(field.annotation)
    shape, item = _shape(annotation)
    if choices is not None:
        shape, item = "choice", tuple(choices)
    extra = _extra(field)
    flag = "--" + option_name(name, field)
    help_text = field.description or ""
    required = field.is_required() and not optional
    default: Any
    if shape == "choice":
        kind: Any = _choices(name, item)
        default = ... if required else (None if field.default is None or optional else kind(str(field.default)))
    elif shape == "scalar":
        kind = Path if extra.get("path") else item
        # An empty path default means "not given": left out (None), so the model keeps it empty, rather than
        # becoming Path("") == "." and failing the path checks as a directory.
        default = ... if required else (None if optional or field.default is None or field.default == ""
                                        or field.default_factory is not None else field.default)
    elif shape == "list":
        kind = types.GenericAlias(list, (Path if extra.get("path") else item,))
        default = ... if required else None
    else:
        kind = list[str]
        default = None
        help_text += "" if shape == "model" or "=" in help_text else " (KEY=VALUE)"
    if default is None:
        kind = kind | None
    if shape == "list":
        help_text += " (repeat the option)"
    metavar = {"mapping": "KEY=VALUE", "pairs": "KEY=LOW,HIGH", "model": "KEY=VALUE"}.get(shape)
    option = typer.Option(flag, help=help_text, show_default=default not in (None, ...), metavar=metavar)
    param_name = option_name(name, field).replace("-", "_")
    return inspect.Parameter(param_name, inspect.Parameter.KEYWORD_ONLY, default=default,
                             annotation=Annotated[kind, option]), shape


def _key_values(values: list[str], flag: str, pairs: bool) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for text in values:
        key, sep, value = text.partition("=")
        if not sep or not key.strip():
            raise DualtwinError(f"{flag}: expected KEY={'LOW,HIGH' if pairs else 'VALUE'}, got {text!r}")
        if pairs:
            parts = value.split(",")
            if len(parts) != 2:
                raise DualtwinError(f"{flag}: expected KEY=LOW,HIGH, got {text!r}")
            out[key.strip()] = [p.strip() for p in parts]
        else:
            out[key.strip()] = value.strip()
    return out


def model_options(model: type[BaseModel], *, optional: Collection[str] = (),
                  choices: dict[str, Collection[str]] | None = None) -> Callable[[Any], Any]:
    """Decorate a command ``fn(*, fields: dict, ...own options)`` with one option per field of ``model``.

    ``optional`` names required fields the command may fill itself (their options become optional);
    ``choices`` narrows ``str`` fields to a closed set on the command line (e.g. twin names, where the library
    also takes a path), so ``--help`` lists it.
    """
    fields = cli_fields(model)
    params: list[inspect.Parameter] = []
    shapes: dict[str, tuple[str, Shape, str]] = {}
    for name, field in fields.items():
        param, shape = _option(name, field, name in optional, (choices or {}).get(name))
        params.append(param)
        shapes[param.name] = (name, shape, "--" + option_name(name, field))

    def decorate(fn: Callable[..., Any]) -> Callable[..., Any]:
        own = [p for p in inspect.signature(fn, eval_str=True).parameters.values() if p.name != "fields"]
        clash = {p.name for p in own} & set(shapes)
        if clash:
            raise TypeError(f"{fn.__name__}: options {sorted(clash)} are also fields of {model.__name__}")

        def command(**kwargs: Any) -> Any:
            given: dict[str, Any] = {}
            for param_name, (name, shape, flag) in shapes.items():
                value = kwargs.pop(param_name)
                if value is None:
                    continue
                if isinstance(value, enum.Enum):
                    value = value.value
                elif isinstance(value, Path):
                    value = str(value)
                elif shape in ("mapping", "pairs", "model"):
                    value = _key_values(list(value), flag, shape == "pairs")
                elif shape == "list":
                    value = [str(v) if isinstance(v, Path) else v for v in value]
                given[name] = value
            return fn(fields=given, **kwargs)

        # Required options first, as Python wants no default before a parameter without one.
        ordered = sorted([*params, *own], key=lambda p: p.default is not inspect.Parameter.empty
                         and p.default is not ...)
        command.__signature__ = inspect.Signature(ordered)  # type: ignore[attr-defined]
        command.__annotations__ = {p.name: p.annotation for p in ordered}
        command.__name__ = fn.__name__
        command.__qualname__ = fn.__qualname__
        command.__doc__ = fn.__doc__
        command.__module__ = fn.__module__
        return command

    return decorate


def validate_model(model: type[BaseModel], values: dict[str, Any]) -> Any:
    """``model(**values)``, its first validation error as one line naming the option."""
    try:
        return model.model_validate(values)
    except ValidationError as exc:
        error = exc.errors()[0]
        loc = [str(part) for part in error["loc"]]
        field = model.model_fields.get(loc[0]) if loc else None
        flag = "--" + option_name(loc[0], field) if field is not None else (loc[0] if loc else model.__name__)
        where = flag + ("" if len(loc) < 2 else " " + ".".join(loc[1:]))
        raise DualtwinError(f"{where}: {error['msg']}") from None


def option_names(command: Any) -> set[str]:
    """The long option names of a click command (for tests comparing a command with its model)."""
    return {opt[2:] for param in command.params for opt in param.opts if opt.startswith("--")}
