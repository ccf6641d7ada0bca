"""Validates a JSON instance against a JSON Schema: validate_json.py INSTANCE SCHEMA.

Every *.schema.json beside SCHEMA is registered under its $id, so a schema may
refer to another by that id (the paper result embeds a tuning report).

Exit 0: valid. Exit 3: not valid (the reason on stderr). Anything else (jsonschema
not installed: exit 1 from the ImportError) is a broken test set-up, never a pass.
"""
import json
import pathlib
import sys

import jsonschema

instance = json.load(open(sys.argv[1]))
schema_path = pathlib.Path(sys.argv[2])
schema = json.load(open(schema_path))
others = [json.load(open(path)) for path in schema_path.parent.glob("*.schema.json")]
cls = jsonschema.validators.validator_for(schema)
try:
    # jsonschema 4.18 and later: schemas found through a registry.
    from referencing import Registry, Resource
except ImportError:
    # Debian 12's python3-jsonschema (4.10), which scripts/bootstrap installs:
    # the same lookup through a resolver's store. Its resolver joins references
    # with urllib, which joins nothing onto a "urn:" base unless told it may.
    import urllib.parse

    urllib.parse.uses_relative.append("urn")
    urllib.parse.uses_fragment.append("urn")
    store = {other["$id"]: other for other in others if "$id" in other}
    validator = cls(schema, resolver=jsonschema.RefResolver.from_schema(schema, store=store))
else:
    registry = Registry()
    for other in others:
        if "$id" in other:
            registry = registry.with_resource(other["$id"], Resource.from_contents(other))
    validator = cls(schema, registry=registry)
errors = sorted(validator.iter_errors(instance), key=lambda e: list(e.absolute_path))
if errors:
    error = errors[0]
    print(f"{sys.argv[1]}: {error.message} (at {list(error.absolute_path)})", file=sys.stderr)
    sys.exit(3)
