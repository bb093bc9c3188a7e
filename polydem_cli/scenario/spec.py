"""The schema machinery lives in :mod:`polydem_cli.params` (lowest layer) so that interaction families
can declare their own scenario tables; re-exported here for the scenario layer and its callers."""

from ..params import (  # noqa: F401
    INT_LIMIT,
    NOVALUE,
    REQUIRED,
    ArrayOf,
    MapOf,
    Param,
    ScenarioError,
    Table,
    markdown,
)
