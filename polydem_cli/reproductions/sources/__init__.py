"""The numbers of the three sources that the reproduction studies compare against, as data files beside the
code that reads them: Schneider (2012) chapters 5 and 7, Luding & Herrmann (biaxial box of cohesive disks),
Sorg (2014) (adaptive coupling); and the published experiments of the validation suite (``polydem study
validate``: Kupfer 1969, Hordijk 1991, Petersson 1981, the size effect).  Each file cites the section, table or
public copy of its numbers."""

from __future__ import annotations

import tomllib
from importlib.resources import files


def source(name: str) -> dict:
    """The numbers of one source file (``name`` without ``.toml``)."""
    return tomllib.loads(files(__package__).joinpath(f"{name}.toml").read_text(encoding="utf-8"))
