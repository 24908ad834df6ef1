"""The benchmark behind ``snapshot bench``: cases (:mod:`~snapcore.bench.cases`) registered
in :mod:`~snapcore.bench.registry` and timed by :mod:`~snapcore.bench.runner`."""
