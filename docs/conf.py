"""Sphinx configuration of the AmbieGen-ROS manual (Markdown pages, parsed by MyST).

Build: ``.venv/bin/python -m sphinx -W -b html docs docs/_build/html`` (docs/testing.md);
``test/test_docs.py`` runs the same build and fails on any warning or broken link.
"""

project = "AmbieGen-ROS"
author = "AmbieGen-ROS team"
copyright = "AmbieGen-ROS team"

extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
root_doc = "index"

# Every heading down to level 4 gets a GitHub-style anchor, so `page.md#section` links work the
# same here and on GitHub (README.md links into the pages this way; test/test_docs.py checks them).
myst_heading_anchors = 4

# docs/results/** holds generated output (experiment reports written by `ambiegen experiment`,
# docs/results/nav2/README.md written by bench/nav2_maps.py). It builds without a warning, so it is
# included, not excluded: index.md lists each report under "Generated reports" (a new one needs a line
# there, or the build warns that it is in no toctree). A regenerated report that warns fails
# test/test_docs.py, which is where it should be noticed; exclude it here ("results/**") only if
# it cannot be made to build.
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]

html_theme = "alabaster"
html_title = "AmbieGen-ROS manual"
