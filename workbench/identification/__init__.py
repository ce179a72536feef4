"""Block-wise system identification of a voyage, one module per responsibility.

:mod:`~workbench.identification.options` (what a run is asked to do),
:mod:`~workbench.identification.planning` (which files, which blocks),
:mod:`~workbench.identification.engine` (one block identified),
:mod:`~workbench.identification.voyage` (every block, in parallel and resumable),
:mod:`~workbench.identification.export` (the store as contract tables),
:mod:`~workbench.identification.figures` and :mod:`~workbench.identification.crosscheck`
(a few blocks identified again). :mod:`workbench.identify` gathers their names.
"""
