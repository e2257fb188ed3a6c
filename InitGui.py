# tsplcam: FreeCAD GUI start-up. Defines the workbench; commands load on activation.
import FreeCADGui


class TsplcamWorkbench(FreeCADGui.Workbench):
    """Five-axis finishing of T-spline mold surfaces."""

    MenuText = "T-spline CAM"
    ToolTip = "Five-axis finishing paths without retraction for T-spline mold surfaces"

    def __init__(self):
        import os
        import tsplcam
        self.__class__.Icon = os.path.join(tsplcam.resource_dir(), "icons", "tsplcam.svg")

    def Initialize(self):
        from tsplcam.workbench import commands, validity
        from tsplcam.workbench.settingspanel import PreferencesPage
        names = commands.register()
        self.appendToolbar("tsplcam", [n for n in names if n != "Tsplcam_About"])
        self.appendMenu("T-spline CAM", names)
        FreeCADGui.addPreferencePage(PreferencesPage, "T-spline CAM")
        validity.install()

    def Activated(self):
        pass

    def Deactivated(self):
        pass

    def GetClassName(self):
        return "Gui::PythonWorkbench"


FreeCADGui.addWorkbench(TsplcamWorkbench())
