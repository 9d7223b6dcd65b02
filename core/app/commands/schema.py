"""``platform schema``: print the JSON Schema of a file format."""

from __future__ import annotations

import importlib
import json

import click

__all__ = ["FORMATS", "command"]

FORMATS: dict[str, str] = {"configuration": "io:ConfigurationFile", "plan": "plan:PlanFile"}
"""File format -> ``module:model`` of :mod:`msrr.core` (a pydantic model, imported when the
command runs, not at ``--help``)."""


@click.command("schema")
@click.argument("file_format", type=click.Choice(sorted(FORMATS)), default="configuration")
def command(file_format: str) -> None:
    """Print the JSON Schema of a file FORMAT (configuration or plan)."""
    module, name = FORMATS[file_format].split(":")
    model = getattr(importlib.import_module(f"...{module}", __package__), name)
    click.echo(json.dumps(model.model_json_schema(), indent=2))
