"""mipdist: the release archive of st_lib (dist/, installed by `make venv`). mkdist writes the
archive (`make dist`) and computes the import order of st_lib (`dist/mkdist.py --import-order`)."""
