"""Design conformance: reusable checks behind ``pytest tests/property``.

- :mod:`.phase_table`: the reference table of which phases each transition
  runs, and its comparison with a model;
- :mod:`.recorder`: parts that record every hook call, and the checks run
  on what they recorded (phases per move, hooks that finish, progress);
- :mod:`.live`: a live controller built for a model, with recorder parts;
- :mod:`.scenarios`: scripted calls that take a live controller through
  every transition that runs phases;
- :mod:`.designs`: managers built from a process file, and the checks of
  their designs' Fixed and Follower rows.

See docs/conformance.md.
"""
