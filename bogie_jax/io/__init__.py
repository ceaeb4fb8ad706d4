"""File input and output (the only part of the package that touches files)."""

from ._measurement import (
    load_measurement as load_measurement,
    save_measurement as save_measurement,
)
from ._report import (
    VERDICTS_FORMAT as VERDICTS_FORMAT,
    check_date as check_date,
    read_verdicts as read_verdicts,
    verdicts_record as verdicts_record,
    write_report as write_report,
    write_trend_report as write_trend_report,
    write_trends as write_trends,
    write_verdicts as write_verdicts,
)
from ._track_csv import (
    load_run_tracks as load_run_tracks,
    load_track as load_track,
    load_track_csv as load_track_csv,
    save_track_csv as save_track_csv,
)
from ._trajectory import save_trajectory as save_trajectory
