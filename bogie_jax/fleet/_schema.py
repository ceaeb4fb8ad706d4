"""The fleet database's tables (SQLAlchemy Core), as of the latest schema version.

- `schema_version`: one row, the version the migrations brought the database to
  (`_migrations.py`);
- `runs`: one row per `bogie-jax fleet run` (or `import`): when it started and finished, the
  code version (`code_version()`), the command, the engine, how many bogie-dates it judged and
  how many failed;
- `judgements`: one row per bogie and date judged, unique on `(bogie_id, date)`: the vehicle,
  layout, code version, run, headline figures (alarms, watches, runs used, whether the fit
  explains the data) and `record`, the whole `verdicts.json` object as JSON text;
- `verdicts`: one row per element or group of a judgement: verdict, watch, estimate, standard
  error, 95 % interval, band and unit;
- `fits`: one row per judgement: the joint fit's status, steps, cost, condition and misfit;
- `failures`: one row per bogie-date whose judging failed, with the error (a later run tries
  it again).

A judgement, its verdicts and its fit are written in one transaction (`_store.py`).
"""

import sqlalchemy as sa


metadata = sa.MetaData()

schema_version = sa.Table(
    "schema_version",
    metadata,
    sa.Column("version", sa.Integer, nullable=False),
)

runs = sa.Table(
    "runs",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("started_at", sa.String(32), nullable=False),
    sa.Column("finished_at", sa.String(32)),
    sa.Column("code_version", sa.String(80), nullable=False),
    sa.Column("command", sa.Text, nullable=False),
    sa.Column("engine", sa.String(200), nullable=False),
    sa.Column("host", sa.String(200), nullable=False),
    sa.Column("judged", sa.Integer, nullable=False, default=0),
    sa.Column("failed", sa.Integer, nullable=False, default=0),
)

judgements = sa.Table(
    "judgements",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("bogie_id", sa.String(200), nullable=False),
    sa.Column("date", sa.String(10), nullable=False),
    sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id")),
    sa.Column("created_at", sa.String(32), nullable=False),
    sa.Column("code_version", sa.String(80), nullable=False),
    sa.Column("vehicle", sa.String(80), nullable=False),
    sa.Column("layout", sa.String(80), nullable=False),
    sa.Column("source", sa.Text, nullable=False),
    sa.Column("false_alarm_rate", sa.Float),
    sa.Column("n_alarms", sa.Integer, nullable=False),
    sa.Column("n_watches", sa.Integer, nullable=False),
    sa.Column("runs_used", sa.Integer, nullable=False),
    sa.Column("runs_total", sa.Integer, nullable=False),
    sa.Column("explains_data", sa.Boolean, nullable=False),
    sa.Column("wall_s", sa.Float),
    sa.Column("record", sa.Text, nullable=False),
    sa.UniqueConstraint("bogie_id", "date", name="uq_judgement_bogie_date"),
)

verdicts = sa.Table(
    "verdicts",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column(
        "judgement_id",
        sa.Integer,
        sa.ForeignKey("judgements.id", ondelete="CASCADE"),
        nullable=False,
        index=True,
    ),
    sa.Column("position", sa.Integer, nullable=False),
    sa.Column("name", sa.String(200), nullable=False),
    sa.Column("verdict", sa.String(32), nullable=False),
    sa.Column("watch", sa.String(8)),
    sa.Column("estimate", sa.Float),
    sa.Column("std_error", sa.Float),
    sa.Column("ci_lo", sa.Float),
    sa.Column("ci_hi", sa.Float),
    sa.Column("band_lo", sa.Float, nullable=False),
    sa.Column("band_hi", sa.Float, nullable=False),
    sa.Column("failed_below", sa.Float),
    sa.Column("failed_above", sa.Float),
    sa.Column("unit", sa.String(40), nullable=False),
    sa.Column("reason", sa.Text, nullable=False),
)

fits = sa.Table(
    "fits",
    metadata,
    sa.Column(
        "judgement_id",
        sa.Integer,
        sa.ForeignKey("judgements.id", ondelete="CASCADE"),
        primary_key=True,
    ),
    sa.Column("status", sa.String(32), nullable=False),
    sa.Column("steps", sa.Integer),
    sa.Column("evaluations", sa.Integer),
    sa.Column("cost", sa.Float),
    sa.Column("condition_number", sa.Float),
    sa.Column("misfit_ratio", sa.Float),
    sa.Column("explains_data", sa.Boolean, nullable=False),
)

failures = sa.Table(
    "failures",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id")),
    sa.Column("bogie_id", sa.String(200), nullable=False),
    sa.Column("date", sa.String(10), nullable=False),
    sa.Column("created_at", sa.String(32), nullable=False),
    sa.Column("code_version", sa.String(80), nullable=False),
    sa.Column("error", sa.Text, nullable=False),
)
