"""The bundled example scenes, studies and validation files, installed as package data `crashlab.examples`
(crashlab.tools.examples; `crashlab examples` lists them, `crashlab examples copy DIR` writes them out)."""
