"""A stand-in for bpy.types.UILayout that checks what a panel asks of it, for background mode, where
Blender draws no UI. Every call is checked against Blender's own RNA: the layout function exists
and takes those keyword names, icons are Blender icons, `prop` names a property the data really
has, `operator` names a registered operator and only its real properties are set. So a draw
function that would raise in the real sidebar raises here. Imports bpy: only for tests/blender."""

from __future__ import annotations

from typing import Any, cast

import bpy

# bl_rna is the class's RNA Struct (the stubs know it as BlenderRNA only; Blender 4.2's is not an
# instance of bpy.types.Struct at run time, so this is a cast, not an assert).
_LAYOUT = cast(bpy.types.Struct, bpy.types.UILayout.bl_rna)
_FUNCTIONS = _LAYOUT.functions
_ICON = _FUNCTIONS["prop"].parameters["icon"]
assert isinstance(_ICON, bpy.types.EnumProperty)
_ICONS = set(_ICON.enum_items.keys())
_CONTAINERS = ("row", "column", "box", "split", "column_flow", "grid_flow")


class OperatorButton:
    """The properties of an operator button: only the operator's own properties can be set."""

    idname: str
    values: dict[str, Any]
    _names: set[str]

    def __init__(self, idname: str) -> None:
        module, name = idname.split(".")
        rna = getattr(getattr(bpy.ops, module), name).get_rna_type()
        object.__setattr__(self, "idname", idname)
        object.__setattr__(self, "_names", {p.identifier for p in rna.properties} - {"rna_type"})
        object.__setattr__(self, "values", {})

    def __setattr__(self, name: str, value: Any) -> None:
        assert name in self._names, f"operator {self.idname} has no property '{name}'"
        self.values[name] = value


class Recorder:
    """Records every item a draw function adds (kind, text or property, operator values)."""

    def __init__(self, items: list[tuple] | None = None) -> None:
        self.items: list[tuple] = [] if items is None else items
        self.use_property_split = False
        self.scale_y = 1.0
        self.enabled = True
        self.active = True

    def __getattr__(self, name: str) -> Any:
        assert name in _FUNCTIONS, f"UILayout has no function '{name}'"
        if name in _CONTAINERS:
            return lambda *args, **kwargs: self._check(name, kwargs) or Recorder(self.items)
        return lambda *args, **kwargs: self._add(name, args, kwargs)

    def _check(self, function: str, kwargs: dict[str, Any]) -> None:
        parameters = _FUNCTIONS[function].parameters
        for key, value in kwargs.items():
            assert key in parameters, f"UILayout.{function} takes no '{key}'"
            if key == "icon":
                assert value in _ICONS, f"'{value}' is not a Blender icon"

    def _add(self, function: str, args: tuple, kwargs: dict[str, Any]) -> Any:
        self._check(function, kwargs)
        if function in ("prop", "prop_search"):
            data, name = args[0], args[1]
            assert name in data.bl_rna.properties, f"{data.bl_rna.identifier} has no property '{name}'"
            if function == "prop_search":
                assert args[3] in args[2].bl_rna.properties, f"no collection '{args[3]}' to search"
            self.items.append((function, name))
            return None
        if function == "operator":
            button = OperatorButton(args[0])
            self.items.append(("operator", args[0], button.values))
            return button
        if function == "template_list":
            list_type, _list_id, data, collection, active_data, active_name = args[:6]
            assert hasattr(bpy.types, list_type), f"UIList '{list_type}' is not registered"
            assert collection in data.bl_rna.properties and active_name in active_data.bl_rna.properties
            self.items.append(("template_list", list_type, collection))
            return None
        self.items.append((function, kwargs.get("text", args[0] if args else "")))
        return None

    def texts(self) -> list[str]:
        return [str(item[1]) for item in self.items if item[0] in ("label", "progress")]

    def operators(self) -> list[str]:
        return [item[1] for item in self.items if item[0] == "operator"]


def filter_items(
    ui_list: type, owner: object, context: bpy.types.Context, data: Any, property: str
) -> tuple[list[int], list[int]]:
    """Run a UIList's filter_items on `owner` (a stand-in for the list): its flags and order."""
    return ui_list.filter_items(owner, context, data, property)


def draw_item(ui_list: type, owner: object, context: bpy.types.Context, data: Any, item: Any, index: int) -> Recorder:
    """Run a UIList's draw_item on `owner` (a stand-in for the list) with a Recorder as the row's
    layout (no icon, no active data); the recorder, for its items."""
    row = Recorder()
    ui_list.draw_item(owner, context, row, data, item, 0, None, "", index)
    return row


def draw(panel: type, context: bpy.types.Context) -> Recorder:
    """Run a Panel's (or Menu's) draw with a Recorder as its layout; the recorder, for its items."""
    layout = Recorder()
    holder = type("Drawn", (), {"layout": layout})()
    if hasattr(panel, "poll") and not panel.poll(context):
        return layout
    panel.draw(holder, context)
    return layout
