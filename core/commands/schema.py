"""``platform schema``: print the JSON Schema of a file format."""

from __future__ import annotations

import json

import click
from pydantic import BaseModel

from ..io import ConfigurationFile
from ..plan import PlanFile

__all__ = ["FORMATS", "command"]

FORMATS: dict[str, type[BaseModel]] = {"configuration": ConfigurationFile, "plan": PlanFile}


@click.command("schema")
@click.argument("file_format", type=click.Choice(sorted(FORMATS)), default="configuration")
def command(file_format: str) -> None:
    """Print the JSON Schema of a file FORMAT (configuration or plan)."""
    click.echo(json.dumps(FORMATS[file_format].model_json_schema(), indent=2))
