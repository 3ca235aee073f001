"""demscale job service: a FastAPI app, a worker process, a SQLite job store (SQLModel) and an
HDF5 result store (h5py); plots are drawn with matplotlib's object API (no pyplot).

Modules:
    settings     configuration from DEMSCALE_* environment variables, tokens, fingerprints
    guard        ASGI middleware: bearer token (401) and body size (413) before any route
    db           SQLite engine (WAL mode) and sessions
    models       SQLModel classes of studies and runs, the status enum
    transitions  every status change, as conditional UPDATEs
    spec         the study spec: pydantic models derived from the engine's parameter records
    errors       the error model and the OpenAPI answers of each status
    admission    cross-field checks by the engine, size caps, 422 errors
    h5store      the study's HDF5 file (written by engine.io.store.save_study): read back
    plots        PNG rendering from stored results
    routes/      the REST endpoints
    app          the FastAPI application (optionally with an embedded worker)
    worker       ``python -m service.worker``; execute runs one study
"""
