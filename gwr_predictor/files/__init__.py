"""The files and paths a user names: one set of rules to open, size-check and write them.

`user_files`: regular files only, size limits checked on the open descriptor, atomic writes, lock
files; `yaml_safe`: YAML without aliases, its nesting bounded; `limits`: the sizes a recording,
checkpoint or text file may declare, checked before anything of that size is allocated; `json_safe`:
what the package writes as JSON is strict JSON. Every function takes the caller's error class, so
messages stay in the caller's family.
"""
