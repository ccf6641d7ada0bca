"""Validates a JSON instance against a JSON Schema: validate_json.py INSTANCE SCHEMA.

Exit 0: valid. Exit 3: not valid (the reason on stderr). Anything else (jsonschema
not installed: exit 1 from the ImportError) is a broken test set-up, never a pass.
"""
import json
import sys

import jsonschema

instance = json.load(open(sys.argv[1]))
schema = json.load(open(sys.argv[2]))
try:
    jsonschema.validate(instance, schema)
except jsonschema.ValidationError as error:
    print(f"{sys.argv[1]}: {error.message} (at {list(error.absolute_path)})", file=sys.stderr)
    sys.exit(3)
