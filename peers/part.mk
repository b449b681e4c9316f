# peers/: an independent MIP peer in Python (pymodbus), written from the note, not from st_lib,
# so interoperability is tested against a second implementation.
PY_PACKAGES += peers
