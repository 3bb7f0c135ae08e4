"""Edgewise Denoise: denoise Cycles render layers (stills and animations)
with libedgewise, through the project's `edgewise` Python package."""
bl_info = {
    "name": "Edgewise Denoise",
    "author": "Edgewise",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Edgewise Denoise; Image Editor > Sidebar > Edgewise",
    "description": "Denoise Cycles renders (every view layer, stills and animations) with libedgewise",
    "category": "Render",
}

# bpy is imported in register() only, so that `core` (pure Python) can be
# imported and unit-tested without Blender.
classes = ()


def register():
    global classes
    import bpy
    from . import handlers, operators, panels, properties
    settings = properties.build_settings_class()
    classes = (settings,) + operators.classes + panels.classes
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.edgewise = bpy.props.PointerProperty(type=settings)
    handlers.register()


def unregister():
    global classes
    import bpy
    from . import handlers
    handlers.unregister()
    del bpy.types.Scene.edgewise
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
    classes = ()
