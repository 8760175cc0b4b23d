"""Pictures of legsim runs: meshcat animations (``legsim.viz.meshcat_anim``) and matplotlib figures
(``legsim.viz.plots``). The CLI finds the writers through the ``legsim.writers`` entry points, so the
core never imports this package."""
