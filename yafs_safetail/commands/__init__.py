"""The project's commands, one module each with ``main(argv)``: what ``yafs-safetail <command>``
runs (``yafs_safetail.cli``), and what ``experiments/<module>.py`` runs in the checkout (the two
that only read results folders, ``figures`` and ``feasibility``, run as
``python -m yafs_safetail.commands.<module>`` instead).

Each module reads top to bottom: its options, their checks, then the work. Only light modules
(the standard library, ``cli``, ``defaults``, ``settings``) are imported before the arguments
are checked where the command's options allow it, so that ``--help`` and a bad argument answer
at once.
"""
