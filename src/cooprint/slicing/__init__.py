"""Slicer (seed §4.2.1): watertight solid -> layers -> perimeters, skins, infill -> ordered paths."""

from cooprint.slicing.paths import (INFILL, PERIMETER_INNER, PERIMETER_OUTER, ROLE_NAMES, SKIN, TRAVEL,
                                    LayerPaths, extrusion_area, extrusion_spacing)
from cooprint.slicing.slicer import (PackedLayers, SlicedModel, iter_layers, layer_tops, pack_layers, slice_chunks,
                                     slice_solid, unpack_layers)

__all__ = ["INFILL", "PERIMETER_INNER", "PERIMETER_OUTER", "ROLE_NAMES", "SKIN", "TRAVEL", "LayerPaths",
           "PackedLayers", "SlicedModel", "extrusion_area", "extrusion_spacing", "iter_layers", "layer_tops",
           "pack_layers", "slice_chunks", "slice_solid", "unpack_layers"]
