"""``qdcnn reproduce``: each table and figure of the paper, measured on your data, in one report.

>>> from qdcnn.experiments.reproduce import ReproduceSpec, parse_data_option
>>> spec = ReproduceSpec("out", data=[parse_data_option("track2=synthetic:track2:60")])
>>> [e.key for e in spec.datasets()], spec.profile.name
(['track2'], 'full')

The modules: :mod:`.spec` (what runs), :mod:`.runner` (the sections, the output folder,
``report.json``), one module per kind of section (:mod:`.accuracy` Tables I-III,
:mod:`.timing` Table IV, :mod:`.figures` Figs. 2-4, :mod:`.training` Figs. 5-6,
:mod:`.noise` Fig. 7, :mod:`.shadows` shadow quality), :mod:`.plots` and :mod:`.html`.
"""

from qdcnn.experiments.reproduce.context import StageReporter, named_options_config
from qdcnn.experiments.reproduce.model import Section
from qdcnn.experiments.reproduce.runner import (
    PAGE_ORDER,
    SECTIONS,
    ReproduceResult,
    run_reproduce,
)
from qdcnn.experiments.reproduce.spec import (
    FULL,
    QUICK,
    TINY,
    DatasetEntry,
    Profile,
    ReproduceSpec,
    parse_data_option,
)

__all__ = [
    "FULL",
    "PAGE_ORDER",
    "QUICK",
    "SECTIONS",
    "TINY",
    "DatasetEntry",
    "Profile",
    "ReproduceResult",
    "ReproduceSpec",
    "Section",
    "StageReporter",
    "named_options_config",
    "parse_data_option",
    "run_reproduce",
]
