"""Studies of the solvers: what accuracy costs (``accuracy``: its command line; ``measure``: the
runs and the fitted orders; ``report``: the tables, the reading and the plot), against the
readable float64 model (:mod:`rustcloth.reference`). Not imported by the runtime package; the
command line reaches the accuracy study through ``rustcloth.accuracy.main``."""
