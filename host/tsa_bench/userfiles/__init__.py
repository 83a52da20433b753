"""The one reader for every file a user writes: YAML documents (protocols, bench files,
and later thesis records, study files, calibration records) and JSON documents (saved
models), with limits that make any input safe to read.

Typical use::

    from tsa_bench.userfiles import DocumentError, read_yaml

    doc = read_yaml(path, what="bench file")   # raises DocumentError "file:line:col: message"
    data = doc.data()                          # plain dict/list/str/int/float/bool/None
    doc.where("limits", "max_twist_turns")     # "file:12:3", for messages of your own

See :mod:`.yaml_reader` for the limits (size, depth, alias expansion, integer digits,
lone surrogates, tags) and :mod:`.files` for what counts as a readable file.
"""

from tsa_bench.userfiles.errors import DocumentError
from tsa_bench.userfiles.files import check_regular_file, read_text_file
from tsa_bench.userfiles.json_reader import JsonLimits, parse_json, read_json
from tsa_bench.userfiles.yaml_reader import YamlDocument, YamlLimits, parse_yaml, read_yaml

__all__ = ["DocumentError", "check_regular_file", "read_text_file", "JsonLimits", "parse_json", "read_json",
           "YamlDocument", "YamlLimits", "parse_yaml", "read_yaml"]
