"""Studies of the solvers: what accuracy costs (``accuracy``), against an independent float64
reference (``model``). Not imported by the runtime package; the command line reaches the
accuracy study through ``rustcloth.accuracy.main``."""
