"""Edgewise Denoise: denoise Cycles renders (every view layer, stills and
animations) with libedgewise, inside the render, before the compositor,
the render window and the output files see it."""
bl_info = {
    "name": "Edgewise Denoise",
    "author": "Edgewise",
    "version": (0, 3, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Edgewise Denoise",
    "description": "Denoise Cycles renders with libedgewise, as Cycles' own Denoise does",
    "category": "Render",
}

# bpy is imported in register() only, so that `core` (pure Python) can be
# imported and unit-tested without Blender.


def register():
    import bpy
    from . import engine, handlers, operators, panels, properties
    properties.register()
    for cls in operators.classes + panels.classes:
        bpy.utils.register_class(cls)
    handlers.register()
    engine.install()


def unregister():
    import bpy
    from . import engine, handlers, operators, panels, properties
    engine.uninstall()
    handlers.unregister()
    for cls in reversed(operators.classes + panels.classes):
        bpy.utils.unregister_class(cls)
    properties.unregister()
