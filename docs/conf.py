"""
Sphinx configuration for the pages in docs/: MyST Markdown, as rosdoc2 builds for docs.ros.org.

Build: ``python -m sphinx -W --keep-going -b html docs OUT`` (test_docs.py does,
into a temporary directory). The testing API is documented from its docstrings.
"""

import os
from pathlib import Path
import sys

from sphinx import addnodes

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS.parent))  # the source tree's r2d2_sim, as ./run.sh sets it

project = 'r2d2_sim'
extensions = ['myst_parser', 'sphinx.ext.autodoc']
source_suffix = {'.md': 'markdown'}
root_doc = 'index'
exclude_patterns = ['_build']
myst_enable_extensions = []
myst_heading_anchors = 3  # GitHub's heading anchors: node.md#get_joint_info-json
autodoc_member_order = 'bysource'
html_theme = 'alabaster'


def _links_outside_docs(app, doctree) -> None:
    """
    Make links to Markdown files outside docs/ (../README.md, ../bench/README.md) downloads.

    On GitHub they are pages of the repository; Sphinx would take them for
    documents of this project and warn. A file outside the project becomes a
    download link, as MyST already makes of links to other files (../urdf/r2d2.urdf).
    Runs before Sphinx collects the downloads of a document.
    """
    env = app.env
    here = Path(env.doc2path(env.docname)).parent
    for node in list(doctree.findall(addnodes.pending_xref)):
        target = node.get('reftarget', '')
        if (node.get('reftype') != 'myst' or node.get('refdomain') != 'doc'
                or target in env.found_docs):
            continue
        path = Path(target + '.md')
        if path.is_absolute() and path.is_file():
            download = addnodes.download_reference(
                '', '', *node.children, refdomain=None, reftype='myst',
                reftarget=os.path.relpath(path, here), refdoc=env.docname,
                refexplicit=node.get('refexplicit', True))
            node.replace_self(download)


def setup(app):
    """Connect the link rewrite ahead of Sphinx's download collector (priority 500)."""
    app.connect('doctree-read', _links_outside_docs, priority=400)
