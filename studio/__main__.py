"""``python -m studio ...``: the ``studio`` command (``python -X importtime -m studio synth ...`` shows
what a command imports before its work)."""

from studio._entry import main

main()
