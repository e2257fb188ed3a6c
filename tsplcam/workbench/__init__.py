"""Everything of tsplcam that imports FreeCAD: document objects, view providers,
commands, task panels and importers. The engine below never imports this package."""
