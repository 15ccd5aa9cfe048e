"""The accuracy-versus-time study's entry point: ``rustcloth.accuracy.main(argv) -> int``.

The study itself lives in ``rustcloth.study.accuracy`` (run it with ``python -m rustcloth
accuracy``; ``--help`` lists its options). Its plot needs matplotlib, imported only when the
study runs: without it the command says which extra to install and exits with status 2.
"""

from __future__ import annotations

from .study.accuracy import Case, Run, main, pareto

__all__ = ["Case", "Run", "main", "pareto"]
