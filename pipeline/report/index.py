from pathlib import Path
def write_run_index(run_dir, stages, title, meta):
    p = Path(run_dir) / "index.html"
    p.write_text("<html><body>" + "".join(f"<a href='{Path(v).relative_to(run_dir)}'>{k}</a>" for s in stages.values() for k, v in s.items()) + "</body></html>")
    return p
