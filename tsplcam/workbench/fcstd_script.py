"""Run by ``freecadcmd`` for ``job --fcstd`` (see ``headless``): the job's results as a
document, made by the workbench's makers from the results already computed.

Environment: ``TSPLCAM_FCSTD_JOB`` (the pickled results), ``TSPLCAM_FCSTD_OUT`` (the
.FCStd to save), ``TSPLCAM_FCSTD_RESULT`` (a JSON file: ``{"ok": true, "objects": [...]}``
or ``{"ok": false, "error": "..."}``). Leaves with os._exit: freecadcmd never waits.
"""
import json
import os
import sys
import traceback


def build_document(data: dict, out: str) -> list:
    """Make and save the document (module doc) in this FreeCAD; the objects' descriptions."""
    import FreeCAD
    from tsplcam.workbench import camjob, importer, messages, validity
    from tsplcam.workbench.fields import PATH_FIELDS, PROGRAM_FIELDS
    from tsplcam.workbench.pathobject import make_tool_path
    from tsplcam.workbench.planobject import make_processing_list
    from tsplcam.workbench.programobject import make_program

    messages.show_dialogs = False
    validity.install()
    s = data["settings"]

    def made(obj, what):
        if obj is None:
            said = [t for _, t, err in messages.recorded if err]
            raise RuntimeError(f"{what}: {said[-1] if said else 'failed'}")
        return obj
    name = os.path.splitext(os.path.basename(out))[0] or "tsplcam"
    doc = FreeCAD.newDocument("".join(c if c.isalnum() else "_" for c in name))
    model_obj = made(importer.import_file(data["model_file"], doc), "the model")
    plan = made(make_processing_list(model_obj, data["plist"]), "the processing list")
    path_values = {f.name: s[f.name] for f in PATH_FIELDS}
    path_values["tool_radius"] = float(data["toolpath"].tool_radius)
    path_obj = made(make_tool_path(plan, computed=data["toolpath"], **path_values), "the tool path")
    program_values = {f.name: s[f.name] for f in PROGRAM_FIELDS}
    stock = None
    if data.get("stock") is not None:
        import Mesh
        V, T = data["stock"]
        stock = doc.addObject("Mesh::Feature", "Stock")
        stock.Mesh = Mesh.Mesh([[list(map(float, V[i])) for i in tri] for tri in T])
        program_values["stock"] = stock
    prog = made(make_program(path_obj, computed=data["program"], **program_values), "the program")
    objects = [model_obj, plan, path_obj, prog] + ([stock] if stock is not None else [])
    if camjob.cam_available():
        job = made(camjob.make_cam_job(prog), "the CAM job")
        objects.append(job)
    doc.recompute()
    for o in doc.Objects:
        if validity.failed(o):
            raise RuntimeError(f"{o.Label} is not valid: {validity.status_text(o)}")
    for o in (plan, path_obj, prog):
        why = validity.problem(o)
        if why:
            raise RuntimeError(why)
    doc.saveAs(out)
    return [f"{o.Label} ({o.TypeId})" for o in objects]


def main() -> int:
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    if root not in sys.path:
        sys.path.insert(0, root)
    result = os.environ["TSPLCAM_FCSTD_RESULT"]
    try:
        import pickle
        with open(os.environ["TSPLCAM_FCSTD_JOB"], "rb") as f:
            data = pickle.load(f)
        objects = build_document(data, os.environ["TSPLCAM_FCSTD_OUT"])
        doc = {"ok": True, "objects": objects}
    except Exception as exc:
        traceback.print_exc()
        doc = {"ok": False, "error": " ".join(str(exc).split()) or type(exc).__name__}
    with open(result, "w") as f:
        json.dump(doc, f)
    return 0 if doc["ok"] else 1


# freecadcmd runs a file as a module named after it ("fcstd_script"), python as "__main__";
# imported from the package (tsplcam.workbench.fcstd_script) it does nothing
if __name__ in ("__main__", "fcstd_script"):
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
