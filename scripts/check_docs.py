#!/usr/bin/python3
"""Checks that the documentation stays in the repository and its links hold (docs/architecture.md, ctest Docs).

  scripts/check_docs.py [ROOT]

1. README.md, the front door, has at most 350 lines; the rest of the manual is in docs/.
2. Every relative link of README.md and docs/*.md resolves to a file or folder inside the repository, and its
   anchor (#...) to a heading of the Markdown file it names (GitHub's heading ids).
3. No text in the repository points to the design notes kept outside it (the method, design and style notes of the
   shared folder): their substance is in docs/method.md, docs/documents.md and docs/architecture.md.
4. No public header (include/) and no command-line text (apps/) mentions an issue number: say what is meant.
Prints every problem as FILE:LINE: what, and exits 1 when there is one.
"""
import pathlib
import re
import sys

README_MAX_LINES = 350
# Spelled in pieces so that this file does not match itself.
OUTSIDE_NOTES = re.compile(r'\b(?:METHOD|DESIGN|STYLE)[.]md\b|shared' + '/' + r'docs\b')
ISSUE_NUMBER = re.compile(r'\bissues?\s+#?[0-9]|\bissue:', re.IGNORECASE)
LINK = re.compile(r'!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
CODE_SPAN = re.compile(r'(`+)(?:(?!\1).)+?\1')
HEADING = re.compile(r'^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$')
SKIPPED_FOLDERS = {'.git', 'node_modules', '__pycache__'}


def text_lines(path):
    """The lines of a Markdown file outside fenced code blocks, with their numbers, code spans marked."""
    fence = None
    for number, line in enumerate(path.read_text(encoding='utf-8').splitlines(), 1):
        stripped = line.lstrip()
        marker = stripped[:3]
        if marker in ('```', '~~~'):
            if fence is None:
                fence = marker
            elif marker == fence:
                fence = None
            continue
        if fence is None:
            yield number, CODE_SPAN.sub(code_text, line)


def code_text(match):
    """A code span's text between NUL marks: headings keep it, links are not looked for in it."""
    ticks = len(match.group(1))
    return '\x00' + match.group(0)[ticks:-ticks] + '\x00'


def slug(heading):
    """GitHub's id of a heading: its text, lower case, without punctuation, spaces as hyphens."""
    text = re.sub(r'!?\[([^\]]*)\]\([^)]*\)', r'\1', heading)  # a link shows its text
    text = text.replace('\x00', '').replace('`', '').replace('*', '')
    text = re.sub(r'<[^>]+>', '', text)
    text = re.sub(r'[^\w\- ]', '', text.lower())
    return text.replace(' ', '-')


def anchors(path, cache={}):
    if path not in cache:
        seen = {}
        ids = set()
        for _, line in text_lines(path):
            match = HEADING.match(line)
            if not match:
                continue
            base = slug(match.group(2))
            count = seen.get(base, 0)
            seen[base] = count + 1
            ids.add(base if count == 0 else f'{base}-{count}')
        cache[path] = ids
    return cache[path]


def check_links(root, path, problems):
    where = path.relative_to(root)
    for number, line in text_lines(path):
        # code spans do not hold links: drop their text, keep the rest of the line
        visible = re.sub('\x00[^\x00]*\x00', '', line)
        for match in LINK.finditer(visible):
            target = match.group(1)
            if re.match(r'^[a-z][a-z0-9+.-]*:', target, re.IGNORECASE):  # http:, https:, mailto:
                continue
            file_part, _, anchor = target.partition('#')
            resolved = (path.parent / file_part).resolve() if file_part else path.resolve()
            if root.resolve() not in (resolved, *resolved.parents):
                problems.append(f'{where}:{number}: the link {target} points outside the repository')
                continue
            if not resolved.exists():
                problems.append(f'{where}:{number}: the link {target} names no file ({resolved.relative_to(root.resolve())})')
                continue
            if not anchor:
                continue
            if resolved.suffix != '.md' or not resolved.is_file():
                problems.append(f'{where}:{number}: the link {target} has an anchor into a file that is not Markdown')
            elif anchor not in anchors(resolved):
                problems.append(f'{where}:{number}: the link {target}: {resolved.name} has no heading #{anchor}')


def is_build_folder(folder):
    return (folder / 'CMakeCache.txt').exists() or folder.name.startswith('build')


def repository_files(root):
    stack = [root]
    while stack:
        folder = stack.pop()
        for entry in sorted(folder.iterdir()):
            if entry.is_dir():
                if entry.name not in SKIPPED_FOLDERS and not is_build_folder(entry) and not entry.is_symlink():
                    stack.append(entry)
            elif entry.is_file():
                yield entry


def check_texts(root, problems):
    for path in repository_files(root):
        try:
            text = path.read_text(encoding='utf-8')
        except (UnicodeDecodeError, OSError):
            continue  # binary: MAT files, fuzzing corpora
        relative = path.relative_to(root)
        public = relative.parts[0] in ('include', 'apps')
        for number, line in enumerate(text.splitlines(), 1):
            if OUTSIDE_NOTES.search(line):
                problems.append(f'{relative}:{number}: points to a note outside the repository; use docs/ or say it')
            if public and ISSUE_NUMBER.search(line):
                problems.append(f'{relative}:{number}: a public header or help text names an issue; say what is meant')


def main():
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).resolve().parent.parent)
    problems = []
    readme = root / 'README.md'
    lines = len(readme.read_text(encoding='utf-8').splitlines())
    if lines > README_MAX_LINES:
        problems.append(f'README.md:{lines}: {lines} lines, more than {README_MAX_LINES}: move the detail to docs/')
    for path in [readme, *sorted((root / 'docs').glob('*.md'))]:
        check_links(root, path, problems)
    check_texts(root, problems)
    for problem in problems:
        print(problem)
    if problems:
        print(f'{len(problems)} problem(s) in the documentation', file=sys.stderr)
        return 1
    print(f'the documentation holds: README.md {lines} lines, every link resolves, nothing points outside')
    return 0


if __name__ == '__main__':
    sys.exit(main())
