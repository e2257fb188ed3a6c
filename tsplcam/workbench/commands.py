"""Workbench commands. Each is registered only once it works end to end."""
import FreeCAD
import FreeCADGui

import tsplcam
from tsplcam.workbench.resources import icon


class AboutCommand:
    """Show the version of tsplcam and of the libraries it runs on."""

    def GetResources(self):
        return {"Pixmap": icon("tsplcam"), "MenuText": "About tsplcam",
                "ToolTip": "Version of tsplcam and of numpy, scipy, python-fcl and elkai"}

    def IsActive(self):
        return True

    def Activated(self):
        from tsplcam.cli import dependency_versions
        lines = [f"tsplcam {tsplcam.__version__}"]
        lines += [f"{k}: {v}" for k, v in dependency_versions().items()]
        FreeCAD.Console.PrintMessage("\n".join(lines) + "\n")
        if FreeCAD.GuiUp:
            from PySide import QtGui
            QtGui.QMessageBox.information(FreeCADGui.getMainWindow(), "About tsplcam", "\n".join(lines))


COMMANDS = {
    "Tsplcam_About": AboutCommand,
}


def register():
    """Add the commands to FreeCAD (once) and return their names in toolbar order."""
    existing = set(FreeCADGui.listCommands())
    for name, cls in COMMANDS.items():
        if name not in existing:
            FreeCADGui.addCommand(name, cls())
    return list(COMMANDS)
