"""`--units us` for the command line: the conversion of what is shown lives in crashlab.units ("shown units"),
where the reconstruction's reports use it too; these are its names here."""
from ..units import frame_in, json_in, shown_name, table_from_shown, table_in, unit_in, unit_of, value_in

__all__ = ["frame_in", "json_in", "shown_name", "table_from_shown", "table_in", "unit_in", "unit_of", "value_in"]
