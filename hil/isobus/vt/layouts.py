"""The binary layout of every Virtual Terminal object type (ISO 11783-6, versions 3 to 6).

An object in a pool is its id (2 bytes, little-endian), its type (1 byte) and its attributes in
the order the standard lists them; counts come before the lists they count. Each type's layout
here is that order as a list of items: a fixed attribute (:class:`F`) or a variable part
(:class:`Var`) whose length is an earlier attribute. The parser (:mod:`hil.isobus.vt.codec`)
and the serialiser walk the same list, so a pool that parses serialises back to its bytes.

The attribute ids (AID) of the change attribute command number the changeable fixed attributes
from 1 in this order, as the standard's tables do; counts, and the values, hidden and enabled
states that have commands of their own, have no AID (``aid=False``).

Where the layouts come from: the standard's object definitions as AgIsoStack++ (MIT) reads
them (``isobus_virtual_terminal_working_set_base.cpp`` at 509a920), and, for the types it
does not parse (graphics context, animation, object label reference list, external object
definition/NAME/pointer, colour palette, graphic data, working set special controls, scaled
graphic), the attribute tables of ISO 11783-6 version 6. Those nine are parsed, listed and
kept, never drawn.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum


class ObjectType(IntEnum):
    """Object type codes (ISO 11783-6 Annex B)."""

    WORKING_SET = 0
    DATA_MASK = 1
    ALARM_MASK = 2
    CONTAINER = 3
    SOFT_KEY_MASK = 4
    KEY = 5
    BUTTON = 6
    INPUT_BOOLEAN = 7
    INPUT_STRING = 8
    INPUT_NUMBER = 9
    INPUT_LIST = 10
    OUTPUT_STRING = 11
    OUTPUT_NUMBER = 12
    OUTPUT_LINE = 13
    OUTPUT_RECTANGLE = 14
    OUTPUT_ELLIPSE = 15
    OUTPUT_POLYGON = 16
    OUTPUT_METER = 17
    OUTPUT_LINEAR_BAR_GRAPH = 18
    OUTPUT_ARCHED_BAR_GRAPH = 19
    PICTURE_GRAPHIC = 20
    NUMBER_VARIABLE = 21
    STRING_VARIABLE = 22
    FONT_ATTRIBUTES = 23
    LINE_ATTRIBUTES = 24
    FILL_ATTRIBUTES = 25
    INPUT_ATTRIBUTES = 26
    OBJECT_POINTER = 27
    MACRO = 28
    AUXILIARY_FUNCTION_1 = 29
    AUXILIARY_INPUT_1 = 30
    AUXILIARY_FUNCTION_2 = 31
    AUXILIARY_INPUT_2 = 32
    AUXILIARY_CONTROL_DESIGNATOR_2 = 33
    WINDOW_MASK = 34
    KEY_GROUP = 35
    GRAPHICS_CONTEXT = 36
    OUTPUT_LIST = 37
    EXTENDED_INPUT_ATTRIBUTES = 38
    COLOUR_MAP = 39
    OBJECT_LABEL_REFERENCE_LIST = 40
    EXTERNAL_OBJECT_DEFINITION = 41
    EXTERNAL_REFERENCE_NAME = 42
    EXTERNAL_OBJECT_POINTER = 43
    ANIMATION = 44
    COLOUR_PALETTE = 45
    GRAPHIC_DATA = 46
    WORKING_SET_SPECIAL_CONTROLS = 47
    SCALED_GRAPHIC = 48


#: the VT version that introduced each type (versions 2 and 3 had types 0-33)
INTRODUCED_IN: dict[ObjectType, int] = {t: (3 if t <= 33 else 4 if t <= 43 else
                                            5 if t == 44 else 6) for t in ObjectType}

# --- reference kinds: which object types an attribute may name (NULL always allowed unless
#     stated) -----------------------------------------------------------------------------------
T = ObjectType
FONT = frozenset({T.FONT_ATTRIBUTES})
LINE = frozenset({T.LINE_ATTRIBUTES})
FILL = frozenset({T.FILL_ATTRIBUTES})
NUMVAR = frozenset({T.NUMBER_VARIABLE})
STRVAR = frozenset({T.STRING_VARIABLE})
INPUT_ATTR = frozenset({T.INPUT_ATTRIBUTES, T.EXTENDED_INPUT_ATTRIBUTES})
SOFT_KEY_MASK = frozenset({T.SOFT_KEY_MASK})
MASKS = frozenset({T.DATA_MASK, T.ALARM_MASK})
PICTURE = frozenset({T.PICTURE_GRAPHIC})
OUTPUT_STRING = frozenset({T.OUTPUT_STRING})
ANY = frozenset(ObjectType)
#: objects that are drawn inside a mask, container, key or button (children lists)
DRAWABLE = frozenset({
    T.CONTAINER, T.BUTTON, T.INPUT_BOOLEAN, T.INPUT_STRING, T.INPUT_NUMBER, T.INPUT_LIST,
    T.OUTPUT_STRING, T.OUTPUT_NUMBER, T.OUTPUT_LIST, T.OUTPUT_LINE, T.OUTPUT_RECTANGLE,
    T.OUTPUT_ELLIPSE, T.OUTPUT_POLYGON, T.OUTPUT_METER, T.OUTPUT_LINEAR_BAR_GRAPH,
    T.OUTPUT_ARCHED_BAR_GRAPH, T.PICTURE_GRAPHIC, T.GRAPHICS_CONTEXT, T.ANIMATION,
    T.OBJECT_POINTER, T.EXTERNAL_OBJECT_POINTER, T.AUXILIARY_FUNCTION_2, T.AUXILIARY_INPUT_2,
    T.AUXILIARY_CONTROL_DESIGNATOR_2, T.SCALED_GRAPHIC, T.KEY, T.OBJECT_LABEL_REFERENCE_LIST})
KEYS = frozenset({T.KEY, T.OBJECT_POINTER, T.EXTERNAL_OBJECT_POINTER})
LIST_ITEMS = DRAWABLE - {T.KEY}


@dataclass(frozen=True)
class F:
    """A fixed attribute.

    Attributes
    ----------
    name : str
        The attribute's name (snake case of the standard's).
    fmt : str
        ``struct`` code: B u8, H u16, h i16, I u32, i i32, f float32, Q u64 (NAME).
    ref : frozenset or None
        For an object reference: the types it may name (0xFFFF, no object, is allowed).
    values : tuple or None
        The values the standard allows, for an enumerated attribute.
    maximum : int or None
        The largest value allowed.
    aid : bool
        Whether the change attribute command may change it.
    """

    name: str
    fmt: str
    ref: frozenset[ObjectType] | None = None
    values: tuple[int, ...] | None = None
    maximum: int | None = None
    aid: bool = True


class VarKind(IntEnum):
    """The variable parts of objects."""

    CHILDREN = 1       # object id, x, y (6 bytes each)
    REFS = 2           # object ids (2 bytes each)
    MACROS = 3         # event, macro id (2 bytes; 4 with the version 5 extended reference)
    BYTES = 4          # a string or raw data of the counted length
    POINTS = 5         # polygon points, x and y (4 bytes each)
    RECORDS = 6        # fixed-size records (language codes, palette colours, ...)
    CODE_PLANES = 7    # extended input attributes: plane, ranges of wide characters


@dataclass(frozen=True)
class Var:
    """A variable part whose length is the earlier attribute ``count``.

    ``size`` is the record size of :attr:`VarKind.RECORDS`; ``ref`` the types an object id in
    ``CHILDREN`` or ``REFS`` may name (0xFFFF allowed in ``REFS`` when ``null_ok``).
    """

    kind: VarKind
    name: str
    count: str
    ref: frozenset[ObjectType] | None = None
    size: int = 1
    null_ok: bool = False


Item = F | Var

C = Var(VarKind.CHILDREN, "children", "n_children", DRAWABLE)
M = Var(VarKind.MACROS, "macros", "n_macros")
NC = F("n_children", "B", aid=False)
NM = F("n_macros", "B", aid=False)
COLOUR = F("background_colour", "B")
W = F("width", "H")
H = F("height", "H")
JUSTIFY = F("justification", "B")
FONT_REF = F("font_attributes", "H", ref=FONT)
AUX_TYPE1 = (0, 1, 2)

LAYOUTS: dict[ObjectType, tuple[Item, ...]] = {
    T.WORKING_SET: (COLOUR, F("selectable", "B", values=(0, 1)),
                    F("active_mask", "H", ref=MASKS | {T.WINDOW_MASK}), NC, NM,
                    F("n_languages", "B", aid=False), C, M,
                    Var(VarKind.RECORDS, "languages", "n_languages", size=2)),
    T.DATA_MASK: (COLOUR, F("soft_key_mask", "H", ref=SOFT_KEY_MASK), NC, NM, C, M),
    T.ALARM_MASK: (COLOUR, F("soft_key_mask", "H", ref=SOFT_KEY_MASK),
                   F("priority", "B", values=(0, 1, 2)),
                   F("acoustic_signal", "B", values=(0, 1, 2, 3)), NC, NM, C, M),
    T.CONTAINER: (W, H, F("hidden", "B", values=(0, 1), aid=False), NC, NM, C, M),
    T.SOFT_KEY_MASK: (COLOUR, F("n_keys", "B", aid=False), NM,
                      Var(VarKind.REFS, "keys", "n_keys", KEYS, null_ok=True), M),
    T.KEY: (COLOUR, F("key_code", "B"), NC, NM, C, M),
    T.BUTTON: (W, H, COLOUR, F("border_colour", "B"), F("key_code", "B"), F("options", "B"),
               NC, NM, C, M),
    T.INPUT_BOOLEAN: (COLOUR, W, F("foreground_colour", "H", ref=FONT),
                      F("variable_reference", "H", ref=NUMVAR),
                      F("value", "B", values=(0, 1), aid=False),
                      F("enabled", "B", values=(0, 1), aid=False), NM, M),
    T.INPUT_STRING: (W, H, COLOUR, FONT_REF, F("input_attributes", "H", ref=INPUT_ATTR),
                     F("options", "B"), F("variable_reference", "H", ref=STRVAR), JUSTIFY,
                     F("length", "B", aid=False), Var(VarKind.BYTES, "value", "length"),
                     F("enabled", "B", values=(0, 1), aid=False), NM, M),
    T.INPUT_NUMBER: (W, H, COLOUR, FONT_REF, F("options", "B"),
                     F("variable_reference", "H", ref=NUMVAR), F("value", "I", aid=False),
                     F("min_value", "I"), F("max_value", "I"), F("offset", "i"),
                     F("scale", "f"), F("decimals", "B", maximum=7),
                     F("format", "B", values=(0, 1)), JUSTIFY, F("options2", "B"), NM, M),
    T.INPUT_LIST: (W, H, F("variable_reference", "H", ref=NUMVAR),
                   F("value", "B", aid=False), F("n_items", "B", aid=False), F("options", "B"),
                   NM, Var(VarKind.REFS, "items", "n_items", LIST_ITEMS, null_ok=True), M),
    T.OUTPUT_STRING: (W, H, COLOUR, FONT_REF, F("options", "B"),
                      F("variable_reference", "H", ref=STRVAR), JUSTIFY,
                      F("length", "H", aid=False), Var(VarKind.BYTES, "value", "length"), NM,
                      M),
    T.OUTPUT_NUMBER: (W, H, COLOUR, FONT_REF, F("options", "B"),
                      F("variable_reference", "H", ref=NUMVAR), F("value", "I", aid=False),
                      F("offset", "i"), F("scale", "f"), F("decimals", "B", maximum=7),
                      F("format", "B", values=(0, 1)), JUSTIFY, NM, M),
    T.OUTPUT_LIST: (W, H, F("variable_reference", "H", ref=NUMVAR),
                    F("value", "B", aid=False), F("n_items", "B", aid=False), NM,
                    Var(VarKind.REFS, "items", "n_items", LIST_ITEMS, null_ok=True), M),
    T.OUTPUT_LINE: (F("line_attributes", "H", ref=LINE), W, H,
                    F("line_direction", "B", values=(0, 1)), NM, M),
    T.OUTPUT_RECTANGLE: (F("line_attributes", "H", ref=LINE), W, H,
                         F("line_suppression", "B", maximum=15),
                         F("fill_attributes", "H", ref=FILL), NM, M),
    T.OUTPUT_ELLIPSE: (F("line_attributes", "H", ref=LINE), W, H,
                       F("ellipse_type", "B", values=(0, 1, 2, 3)),
                       F("start_angle", "B", maximum=180), F("end_angle", "B", maximum=180),
                       F("fill_attributes", "H", ref=FILL), NM, M),
    T.OUTPUT_POLYGON: (W, H, F("line_attributes", "H", ref=LINE),
                       F("fill_attributes", "H", ref=FILL),
                       F("polygon_type", "B", values=(0, 1, 2, 3)),
                       F("n_points", "B", aid=False), NM,
                       Var(VarKind.POINTS, "points", "n_points"), M),
    T.OUTPUT_METER: (W, F("needle_colour", "B"), F("border_colour", "B"),
                     F("arc_and_tick_colour", "B"), F("options", "B"), F("n_ticks", "B"),
                     F("start_angle", "B", maximum=180), F("end_angle", "B", maximum=180),
                     F("min_value", "H"), F("max_value", "H"),
                     F("variable_reference", "H", ref=NUMVAR), F("value", "H", aid=False),
                     NM, M),
    T.OUTPUT_LINEAR_BAR_GRAPH: (W, H, F("colour", "B"), F("target_line_colour", "B"),
                                F("options", "B"), F("n_ticks", "B"), F("min_value", "H"),
                                F("max_value", "H"), F("variable_reference", "H", ref=NUMVAR),
                                F("value", "H", aid=False),
                                F("target_value_variable_reference", "H", ref=NUMVAR),
                                F("target_value", "H"), NM, M),
    T.OUTPUT_ARCHED_BAR_GRAPH: (W, H, F("colour", "B"), F("target_line_colour", "B"),
                                F("options", "B"), F("start_angle", "B", maximum=180),
                                F("end_angle", "B", maximum=180), F("bar_graph_width", "H"),
                                F("min_value", "H"), F("max_value", "H"),
                                F("variable_reference", "H", ref=NUMVAR),
                                F("value", "H", aid=False),
                                F("target_value_variable_reference", "H", ref=NUMVAR),
                                F("target_value", "H"), NM, M),
    T.PICTURE_GRAPHIC: (W, F("actual_width", "H", aid=False),
                        F("actual_height", "H", aid=False),
                        F("format", "B", values=(0, 1, 2), aid=False), F("options", "B"),
                        F("transparency_colour", "B"), F("n_raw_bytes", "I", aid=False), NM,
                        Var(VarKind.BYTES, "raw_data", "n_raw_bytes"), M),
    T.NUMBER_VARIABLE: (F("value", "I", aid=False),),
    T.STRING_VARIABLE: (F("length", "H", aid=False), Var(VarKind.BYTES, "value", "length")),
    T.FONT_ATTRIBUTES: (F("font_colour", "B"), F("font_size", "B", maximum=14),
                        F("font_type", "B", values=(0, 1, 2, 4, 5, 7, 0xFF)),
                        F("font_style", "B"), NM, M),
    T.LINE_ATTRIBUTES: (F("line_colour", "B"), F("line_width", "B"), F("line_art", "H"), NM,
                        M),
    T.FILL_ATTRIBUTES: (F("fill_type", "B", values=(0, 1, 2, 3)), F("fill_colour", "B"),
                        F("fill_pattern", "H", ref=PICTURE), NM, M),
    T.INPUT_ATTRIBUTES: (F("validation_type", "B", values=(0, 1)),
                         F("length", "B", aid=False),
                         Var(VarKind.BYTES, "validation_string", "length"), NM, M),
    T.OBJECT_POINTER: (F("value", "H", ref=ANY, aid=False),),
    T.MACRO: (F("n_bytes", "H", aid=False), Var(VarKind.BYTES, "commands", "n_bytes")),
    T.AUXILIARY_FUNCTION_1: (COLOUR, F("function_type", "B", values=AUX_TYPE1), NC, C),
    T.AUXILIARY_INPUT_1: (COLOUR, F("function_type", "B", values=AUX_TYPE1),
                          F("input_id", "B", maximum=250), NC, C),
    T.AUXILIARY_FUNCTION_2: (COLOUR, F("function_attributes", "B"), NC, C),
    T.AUXILIARY_INPUT_2: (COLOUR, F("function_attributes", "B"), NC, C),
    T.AUXILIARY_CONTROL_DESIGNATOR_2: (
        F("pointer_type", "B", values=(0, 1, 2, 3)),
        F("auxiliary_object_id", "H",
          ref=frozenset({T.AUXILIARY_FUNCTION_2, T.AUXILIARY_INPUT_2}))),
    T.WINDOW_MASK: (F("window_width", "B", values=(1, 2)),
                    F("window_height", "B", values=(1, 2, 3, 4, 5, 6)),
                    F("window_type", "B", maximum=18), COLOUR, F("options", "B"),
                    F("name", "H", ref=OUTPUT_STRING | {T.OBJECT_POINTER}),
                    F("window_title", "H", ref=OUTPUT_STRING | {T.OBJECT_POINTER}),
                    F("window_icon", "H", ref=DRAWABLE),
                    F("n_object_refs", "B", aid=False), NC, NM,
                    Var(VarKind.REFS, "object_refs", "n_object_refs", DRAWABLE,
                        null_ok=True), C, M),
    T.KEY_GROUP: (F("options", "B"), F("name", "H", ref=OUTPUT_STRING | {T.OBJECT_POINTER}),
                  F("key_group_icon", "H", ref=DRAWABLE), F("n_keys", "B", aid=False),
                  Var(VarKind.REFS, "keys", "n_keys", KEYS), NM, M),
    T.GRAPHICS_CONTEXT: (F("viewport_width", "H"), F("viewport_height", "H"),
                         F("viewport_x", "h"), F("viewport_y", "h"), F("canvas_width", "H"),
                         F("canvas_height", "H"), F("viewport_zoom", "f"),
                         F("cursor_x", "h"), F("cursor_y", "h"),
                         F("foreground_colour", "B"), COLOUR, FONT_REF,
                         F("line_attributes", "H", ref=LINE),
                         F("fill_attributes", "H", ref=FILL),
                         F("format", "B", values=(0, 1, 2)), F("options", "B"),
                         F("transparency_colour", "B")),
    T.EXTENDED_INPUT_ATTRIBUTES: (F("validation_type", "B", values=(0, 1)),
                                  F("n_code_planes", "B", aid=False),
                                  Var(VarKind.CODE_PLANES, "code_planes", "n_code_planes")),
    T.COLOUR_MAP: (F("n_indexes", "H", values=(2, 16, 256), aid=False),
                   Var(VarKind.BYTES, "indexes", "n_indexes")),
    T.OBJECT_LABEL_REFERENCE_LIST: (F("n_labels", "H", aid=False),
                                    Var(VarKind.RECORDS, "labels", "n_labels", size=7)),
    T.EXTERNAL_OBJECT_DEFINITION: (F("options", "B"), F("name", "Q"),
                                   F("n_objects", "B", aid=False),
                                   Var(VarKind.REFS, "objects", "n_objects", ANY)),
    T.EXTERNAL_REFERENCE_NAME: (F("options", "B"), F("name", "Q")),
    T.EXTERNAL_OBJECT_POINTER: (F("default_object", "H", ref=DRAWABLE),
                                F("external_reference_name", "H",
                                  ref=frozenset({T.EXTERNAL_REFERENCE_NAME})),
                                F("external_object", "H")),
    T.ANIMATION: (W, H, F("refresh_interval", "H"), F("value", "B", aid=False),
                  F("enabled", "B", values=(0, 1), aid=False), F("first_child_index", "B"),
                  F("last_child_index", "B"), F("default_child_index", "B"), F("options", "B"),
                  NC, NM, C, M),
    T.COLOUR_PALETTE: (F("options", "H"), F("n_colours", "H", aid=False),
                       Var(VarKind.RECORDS, "colours", "n_colours", size=4)),
    T.GRAPHIC_DATA: (F("format", "B", values=(0, 1, 2)), F("n_bytes", "I", aid=False),
                     Var(VarKind.BYTES, "data", "n_bytes")),
    T.WORKING_SET_SPECIAL_CONTROLS: (
        F("colour_map", "H", ref=frozenset({T.COLOUR_MAP})),
        F("colour_palette", "H", ref=frozenset({T.COLOUR_PALETTE})),
        F("n_language_pairs", "B", aid=False),
        Var(VarKind.RECORDS, "language_pairs", "n_language_pairs", size=4)),
    T.SCALED_GRAPHIC: (W, H, F("scale_type", "B"), F("options", "B"),
                       F("value", "H", ref=frozenset({T.PICTURE_GRAPHIC, T.GRAPHIC_DATA}),
                         aid=False), NM, M),
}

#: the fixed attributes a change attribute command may set, per type: AID -> attribute
ATTRIBUTE_IDS: dict[ObjectType, dict[int, F]] = {}
for _type, _items in LAYOUTS.items():
    _fixed = [i for i in _items if isinstance(i, F) and i.aid]
    ATTRIBUTE_IDS[_type] = dict(enumerate(_fixed, start=1))

#: the masks and the objects a client's command may make visible (working set's children)
TOP_LEVEL = frozenset({T.WORKING_SET, T.DATA_MASK, T.ALARM_MASK, T.SOFT_KEY_MASK,
                       T.WINDOW_MASK, T.KEY_GROUP})
