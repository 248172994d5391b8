"""Validates an OpenAPI document (a JSON file) as OpenAPI 3.1, the way openapi-spec-validator does.

1. The document against the OpenAPI Initiative's 3.1 JSON Schema (`schema.json` of
   https://spec.openapis.org/oas/3.1, as schemathesis bundles it:
   `schemathesis.specs.openapi.definitions.OPENAPI_31`), with jsonschema-rs's Draft 2020-12
   validator: structure, `in` values, a path parameter's `required: true`, ...
2. What that schema cannot state and openapi-spec-validator checks beside it: every `{name}` of a
   path template is a path parameter of each of its operations and every path parameter names one
   of the template's; a parameter (name, in) appears once per operation; operationIds are unique.

Usage: python3 openapi_check.py DOC.json. Prints one JSON line, {"ok": true, "paths": N,
"operations": N, "parameters": {"path": N, "query": N}}, and exits 0; else prints every problem
and exits 1.
"""

import json
import re
import sys

import jsonschema_rs
from schemathesis.specs.openapi.definitions import OPENAPI_31

METHODS = ("get", "put", "post", "delete", "options", "head", "patch", "trace")


def problems(doc):
    found = []
    if not str(doc.get("openapi", "")).startswith("3.1"):
        found.append(f"openapi is {doc.get('openapi')!r}, not 3.1.x")
    validator = jsonschema_rs.Draft202012Validator(OPENAPI_31)
    for e in validator.iter_errors(doc):
        where = "/".join(str(p) for p in e.instance_path)
        found.append(f"schema: at /{where}: {e.message}")
    seen_ids = {}
    counts = {}
    for path, item in doc.get("paths", {}).items():
        template = set(re.findall(r"{([^}]+)}", path))
        shared = item.get("parameters", [])
        for method in METHODS:
            op = item.get(method)
            if op is None:
                continue
            where = f"{method.upper()} {path}"
            params = shared + op.get("parameters", [])
            keys = [(p.get("name"), p.get("in")) for p in params]
            for k in set(keys):
                if keys.count(k) > 1:
                    found.append(f"{where}: parameter {k[0]!r} in {k[1]} given {keys.count(k)} times")
            in_path = {p.get("name") for p in params if p.get("in") == "path"}
            for name in sorted(in_path - template):
                found.append(f"{where}: path parameter {name!r} is not in the path template")
            for name in sorted(template - in_path):
                found.append(f"{where}: the template's {{{name}}} is no path parameter")
            for p in params:
                counts[p.get("in")] = counts.get(p.get("in"), 0) + 1
            op_id = op.get("operationId")
            if op_id is not None:
                if op_id in seen_ids:
                    found.append(f"{where}: operationId {op_id!r} repeats {seen_ids[op_id]}'s")
                seen_ids[op_id] = where
    return found, counts


def main():
    with open(sys.argv[1], encoding="utf-8") as f:
        doc = json.load(f)
    found, counts = problems(doc)
    if found:
        print("\n".join(found))
        sys.exit(1)
    operations = sum(1 for item in doc["paths"].values() for m in METHODS if m in item)
    print(json.dumps({"ok": True, "paths": len(doc["paths"]), "operations": operations, "parameters": counts}))


if __name__ == "__main__":
    main()
