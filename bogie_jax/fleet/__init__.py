"""A fleet: many bogies judged from an inventory, on one machine or a Dask cluster, with their
history in a database (SQLite or PostgreSQL, through SQLAlchemy) and one static HTML page
(`docs/fleet.md`). Needs the `fleet` extra (`pip install "bogie-jax[fleet]"`)."""

from ._engine import (
    DaskEngine as DaskEngine,
    EngineError as EngineError,
    SerialEngine as SerialEngine,
)
from ._import import (
    ImportProblem as ImportProblem,
    import_results as import_results,
    read_results as read_results,
)
from ._inventory import (
    INVENTORY_FORMAT as INVENTORY_FORMAT,
    InventoryError as InventoryError,
    read_inventory as read_inventory,
)
from ._migrations import (
    MIGRATIONS as MIGRATIONS,
    Migration as Migration,
    SchemaError as SchemaError,
    current_version as current_version,
    latest_version as latest_version,
)
from ._page import fleet_page as fleet_page, write_fleet_page as write_fleet_page
from ._pinning import can_pin as can_pin, pin_process as pin_process
from ._run import (
    FleetSummary as FleetSummary,
    pending_tasks as pending_tasks,
    run_fleet as run_fleet,
)
from ._store import FleetStore as FleetStore, open_store as open_store
from ._synthetic import (
    SHORT_RUNS as SHORT_RUNS,
    SyntheticBogie as SyntheticBogie,
    write_synthetic_fleet as write_synthetic_fleet,
)
from ._task import JudgeTask as JudgeTask, Outcome as Outcome
from ._trends import ElementTrend as ElementTrend, element_trends as element_trends
from ._url import StoreError as StoreError
from ._values import (
    BogieEntry as BogieEntry,
    Inventory as Inventory,
    MonitorSettings as MonitorSettings,
    Visit as Visit,
)
