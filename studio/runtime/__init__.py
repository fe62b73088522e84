"""Layer 0, beside the core: the runtime machinery the pipelines run on.

Process teams and parallel maps (:mod:`.parallel`), progress reports (:mod:`.progress`) and
deferred interrupts (:mod:`.interrupts`). Nothing here knows the domain: it imports only the core
(today not even that), reads or writes no dataset, and imports no heavy library.
"""
