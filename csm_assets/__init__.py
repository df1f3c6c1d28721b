"""csm-assets: exact Cone Step Mapping (CSM) step maps for game and film assets."""

from .cones.exact import cone_ratios
from .cones.quadrant import quadrant_cone_ratios
from .cones.relaxed import relaxed_cone_ratios
from .errors import FormatError, OptionError, OutputError
from .formats import load_heightfield, read_step_map, read_step_map_meta, save_heightfield, write_step_map
from .heightfield import Heightfield
from .packing import step_map, unpack_step_map
from .stepmap import StepMap, StepMapSettings, load_step_map, make_step_map, save_step_map
from .verify.trace import trace_heightfield, trace_heightfield_world

__version__ = "0.1.0"

__all__ = [
    "FormatError", "Heightfield", "OptionError", "OutputError", "StepMap", "StepMapSettings",
    "load_step_map", "make_step_map", "save_step_map", "cone_ratios", "load_heightfield",
    "quadrant_cone_ratios", "read_step_map", "read_step_map_meta", "relaxed_cone_ratios", "save_heightfield", "step_map", "trace_heightfield",
    "trace_heightfield_world", "unpack_step_map", "write_step_map",
]
