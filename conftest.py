"""Collection rules shared by the test suite and the docstring examples under src/.

Docstring examples run with ``--doctest-modules``; modules that need an optional extra
are left out of that collection when the extra is not installed, so the base install
(no extras) runs every test and example it can.
"""

from __future__ import annotations

import importlib.util

_EXTRA_MODULES = {
    "torch": ["src/qdcnn/models/*.py", "src/qdcnn/quantum/torch*"],
}

collect_ignore_glob: list[str] = []
for _module, _globs in _EXTRA_MODULES.items():
    if importlib.util.find_spec(_module) is None:
        collect_ignore_glob += _globs
