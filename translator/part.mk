# translator/: stc, the ST-to-C translator (Python, lark). Installed into the venv as `stc`.
PY_PACKAGES += translator
