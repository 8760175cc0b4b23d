"""The bundled scenes (``*.toml``, found by name through ``importlib.resources``) and the scripts
that reproduce the papers' figures (``fig_*.py``, run as ``python -m legsim.scenarios.fig_pronk_snapshots``
or as plain scripts from a checkout)."""
