#!/usr/bin/python3
"""Checks feedid's dependency rules (docs/architecture.md) on the #include lines of the tree.

  scripts/check_layers.py [ROOT]

1. A file in include/feedid/<area>/ or src/<area>/ includes public headers of its own area or of a lower one only
   (the order below); two areas of one rank are independent of each other.
2. A private header ("name.hpp" without feedid/) is included only from its own src/<area>/ folder.
3. apps/, python/, examples/, bench/ and tests/ include the public headers (feedid/...) and their own local headers;
   nothing anywhere includes a path through ../ or src/.
Prints every violation as FILE:LINE: what, and exits 1 when there is one.
"""
import pathlib
import re
import sys

# Rank of each area: a file may include its own area and areas of a strictly lower rank.
RANKS = {
    'core': 0,
    'numeric': 1,
    'model': 2, 'io': 2,
    'identify': 3, 'plan': 3,
    'sim': 4,
    'history': 5,
    'stream': 6,
    'report': 7,
}
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')


def includes(path):
    for number, line in enumerate(path.read_text(encoding='utf-8', errors='replace').splitlines(), 1):
        match = INCLUDE.match(line)
        if match:
            yield number, match.group(1), match.group(2)


def area_of_public(name):
    parts = name.split('/')
    if len(parts) >= 3 and parts[0] == 'feedid':
        return parts[1]
    return None


def check_library(root, problems):
    for top in ('include/feedid', 'src'):
        base = root / top
        for path in sorted(base.rglob('*.[ch]pp')):
            relative = path.relative_to(base)
            if len(relative.parts) < 2:
                problems.append(f'{path.relative_to(root)}:1: outside every area (move it to {top}/<area>/)')
                continue
            area = relative.parts[0]
            if area not in RANKS:
                problems.append(f'{path.relative_to(root)}:1: {area}/ is not an area of {sorted(RANKS)}')
                continue
            for number, quote, name in includes(path):
                where = f'{path.relative_to(root)}:{number}'
                if name.startswith('feedid/'):
                    target = area_of_public(name)
                    if target is None:
                        if name != 'feedid/feedid.hpp':
                            problems.append(f'{where}: {name} is not in an area')
                        continue
                    if target not in RANKS:
                        problems.append(f'{where}: {name}: {target}/ is not an area')
                    elif target != area and RANKS[target] >= RANKS[area]:
                        kind = 'a higher' if RANKS[target] > RANKS[area] else 'a sibling'
                        problems.append(f'{where}: {area} includes {name}, {kind} area ({target})')
                elif quote == '"':
                    if top == 'include/feedid':
                        problems.append(f'{where}: a public header includes the private "{name}"')
                    elif '/' in name or not (path.parent / name).exists():
                        problems.append(f'{where}: "{name}" is not a private header of src/{area}/')


def check_clients(root, problems):
    for top in ('apps', 'python', 'examples', 'bench', 'tests', 'fuzz'):
        for path in sorted((root / top).rglob('*.[ch]pp')):
            for number, quote, name in includes(path):
                where = f'{path.relative_to(root)}:{number}'
                if '..' in name.split('/') or name.startswith('src/'):
                    problems.append(f'{where}: includes "{name}" by a path into the tree; use a public header')
                elif name.startswith('feedid/') and area_of_public(name) is None and name != 'feedid/feedid.hpp':
                    problems.append(f'{where}: {name} is not in an area')


def main():
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).resolve().parent.parent)
    problems = []
    check_library(root, problems)
    check_clients(root, problems)
    for problem in problems:
        print(problem)
    if problems:
        print(f'{len(problems)} include(s) break the layering (docs/architecture.md)', file=sys.stderr)
        return 1
    print('the layering holds: no upward, sideways or private include')
    return 0


if __name__ == '__main__':
    sys.exit(main())
