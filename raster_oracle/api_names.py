"""The names of the Python API, listed once: :mod:`raster_oracle` loads them lazily from
:mod:`raster_oracle.api` (whose ``__all__`` is this list); ``tests/test_api_names.py`` holds
the package's lazy names, ``api.__all__`` and the functions ``api`` defines equal to it."""

API_NAMES = (
    "InputError",
    "ModelError",
    "ReferenceImages",
    "check",
    "export",
    "load_scene",
    "reference",
    "run_model",
    "score_folder",
    "score_image",
    "score_technique",
    "techniques",
    "write_junit",
)
