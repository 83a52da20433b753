"""Output files created exclusively, never through a planted link, whole or not at all
(:mod:`tsa_bench.outputs.files`)."""

from tsa_bench.outputs.files import (
    OutputExists, allow_replace, create_new, open_new, open_output, publish, refuse_existing, replace_allowed, reserve_free_name,
    same_file, save_figure, temp_name, write_text, writing,
)

__all__ = ["OutputExists", "allow_replace", "create_new", "open_new", "open_output", "publish", "refuse_existing", "replace_allowed",
           "reserve_free_name", "same_file", "save_figure", "temp_name", "write_text", "writing"]
