"""mipdist: the release archives of st_lib's two libraries (dist/, installed by `make venv`). mkdist
writes them (`make dist`), checks and prints each library's import order
(`dist/mkdist.py --import-order`) and writes the block references (`--reference`)."""
