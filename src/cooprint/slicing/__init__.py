"""Slicer (seed §4.2.1): watertight solid -> layers -> perimeters, skins, infill -> ordered paths."""

from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER,
                                    PERIMETER_ROLES, ROLE_NAMES, ROUND_ROLES, SKIN, SOLID_ROLES, TOP_SKIN, TRAVEL,
                                    LayerPaths, extrusion_area, extrusion_spacing, flow_area)
from cooprint.slicing.slicer import (PackedLayers, SlicedModel, iter_layers, layer_tops, pack_layers, slice_chunks,
                                     slice_solid, unpack_layers)

__all__ = ["BRIDGE", "GAP_FILL", "INFILL", "OVERHANG", "PERIMETER_INNER", "PERIMETER_OUTER", "PERIMETER_ROLES",
           "ROLE_NAMES", "ROUND_ROLES", "SKIN", "SOLID_ROLES", "TOP_SKIN", "TRAVEL", "LayerPaths",
           "PackedLayers", "SlicedModel", "extrusion_area", "extrusion_spacing", "flow_area", "iter_layers", "layer_tops",
           "pack_layers", "slice_chunks", "slice_solid", "unpack_layers"]
