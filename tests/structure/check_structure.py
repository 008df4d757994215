#!/usr/bin/env python3
"""The shape of the code, checked: layering, function length, file sizes.

  check_structure.py layering ROOT   a file includes only from its own folder and the folders below it
  check_structure.py sizes ROOT      no function in server/ over 120 lines, no client file over 500,
                                     README.md at most 300 lines, docs/benchmarks.md at most 400
  check_structure.py links ROOT      every relative link and picture in the docs leads somewhere: the
                                     file exists, and a #fragment into a markdown file names a heading

Each prints every violation (file:line and why) and exits 1 when there is one.
"""
import re
import sys
from pathlib import Path

# The layers, bottom to top. A folder may include from its own folder and from the folders of lower
# layers, never from a folder of its own layer or above: render and store, and http and cli, are
# strangers to each other. "shaders" is shaders/shared, the struct layouts a shader and its host share.
LAYERS = [
    ["protocol", "shaders"],
    ["vk", "mesh", "image", "volume"],
    ["assets", "gltf"],
    ["passes"],
    ["render", "store"],
    ["http", "cli"],
    ["daemon"],
]
# Lower folders a folder may NOT use although they sit below it: the passes take plain inputs, never the
# scene document or what the store and renderer share.
FORBIDDEN = {
    "passes": {"protocol", "assets", "gltf"},
    "vk": {"shaders"},
}
RANK = {folder: rank for rank, folders in enumerate(LAYERS) for folder in folders}

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')


def folder_of(root: Path, path: Path) -> str:
    rel = path.relative_to(root).parts
    if rel[0] == "server":
        return rel[1]
    if rel[:2] == ("shaders", "shared"):
        return "shaders"
    return rel[0]


def included_folder(own: str, header: str) -> str:
    if "/" in header:
        return header.split("/")[0]
    # A bare name is a sibling in the same folder, or a shared shader header found on the include path.
    return own if own != "shaders" else "shaders"


def sources(root: Path):
    for top in ("protocol", "server", "shaders/shared"):
        for path in sorted((root / top).rglob("*")):
            if path.suffix in (".h", ".cpp", ".glsl", ".comp") and path.is_file():
                yield path


def check_layering(root: Path) -> list[str]:
    problems = []
    for path in sources(root):
        own = folder_of(root, path)
        if own not in RANK:
            problems.append(f"{path.relative_to(root)}: folder '{own}' is in no layer of the table")
            continue
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            match = INCLUDE.match(line)
            if not match:
                continue
            header = match.group(1)
            if "/" not in header and (path.parent / header).exists():
                continue
            target = header.split("/")[0] if "/" in header else "shaders"
            where = f"{path.relative_to(root)}:{number}: includes \"{header}\""
            if target == own:
                continue
            if target not in RANK:
                problems.append(f"{where}, from '{target}', which is in no layer of the table")
            elif RANK[target] >= RANK[own]:
                relation = "beside" if RANK[target] == RANK[own] else "above"
                problems.append(f"{where}, from '{target}', {relation} '{own}'")
            elif target in FORBIDDEN.get(own, set()):
                problems.append(f"{where}: '{own}' never uses '{target}'")
    return problems


# A function's body starts at a '{' whose statement reads like a signature: a parameter list closed
# before it, and no keyword that opens a block of another kind.
NOT_A_FUNCTION = re.compile(
    r"\b(if|for|while|switch|catch|namespace|class|struct|union|enum|do|else|try|return|extern)\b|=\s*$|\[[^\]]*\]\s*\(")


def strip_code(text: str) -> str:
    """Comments, strings and character literals blanked (newlines kept), so braces count true."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("\n" * text.count("\n", i, j))
            i = j
        elif text.startswith('R"', i):
            delim_end = text.find("(", i)
            delim = text[i + 2:delim_end]
            j = text.find(")" + delim + '"', delim_end)
            j = n if j < 0 else j + len(delim) + 2
            out.append('""' + "\n" * text.count("\n", i, j))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def long_functions(path: Path, limit: int) -> list[str]:
    code = strip_code(path.read_text(errors="replace"))
    problems = []
    depth_stack = []  # for each open brace: the line a function began on, or None
    statement_start = 0
    inside_function = 0
    for i, c in enumerate(code):
        if c == "{":
            head = code[statement_start:i]
            is_function = (not inside_function and ")" in head and "(" in head
                           and not NOT_A_FUNCTION.search(head))
            if is_function:
                name = re.findall(r"([~\w:]+)\s*\(", head)
                begin = code.count("\n", 0, i) + 1
                depth_stack.append((begin, name[0] if name else "?"))
                inside_function += 1
            else:
                depth_stack.append(None)
            statement_start = i + 1
        elif c == "}":
            opened = depth_stack.pop() if depth_stack else None
            if opened:
                inside_function -= 1
                begin, name = opened
                end = code.count("\n", 0, i) + 1
                if end - begin + 1 > limit:
                    problems.append(f"{path}:{begin}: {name} is {end - begin + 1} lines (at most {limit})")
            statement_start = i + 1
        elif c == ";":
            statement_start = i + 1
    return problems


def check_sizes(root: Path) -> list[str]:
    problems = []
    for path in sorted((root / "server").rglob("*.cpp")) + sorted((root / "server").rglob("*.h")):
        problems += [p.replace(str(root) + "/", "") for p in long_functions(path, 120)]
    for path in sorted((root / "web-client").rglob("*")):
        if path.suffix in (".js", ".mjs", ".css", ".html") and path.is_file():
            lines = len(path.read_text(errors="replace").splitlines())
            if lines > 500:
                problems.append(f"{path.relative_to(root)}: {lines} lines (a client file holds at most 500)")
    for name, limit in (("README.md", 300), ("docs/benchmarks.md", 400)):
        lines = len((root / name).read_text().splitlines())
        if lines > limit:
            problems.append(f"{name}: {lines} lines (at most {limit}; the rest belongs on a topic page)")
    return problems


MARKDOWN_LINK = re.compile(r'!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^)\s]+)(?:\s+"[^"]*")?\)')


def heading_anchors(path: Path) -> set[str]:
    """The anchors GitHub gives a markdown file's headings (repeats numbered -1, -2, ...)."""
    anchors, seen, in_code = set(), {}, False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            in_code = not in_code
        match = None if in_code else re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not match:
            continue
        text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", match.group(1))
        slug = re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        anchors.add(slug if count == 0 else f"{slug}-{count}")
    return anchors


def check_links(root: Path) -> list[str]:
    problems = []
    pages = [root / "README.md", root / "protocol/README.md", root / "web-client/README.md"]
    pages += sorted((root / "docs").rglob("*.md"))
    for page in pages:
        text = page.read_text()
        # Code is not prose: fenced blocks and inline code are blanked, keeping the line numbers.
        text = re.sub(r"(?ms)^```.*?^```", lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)
        text = re.sub(r"`[^`\n]*`", lambda m: " " * len(m.group(0)), text)
        for match in MARKDOWN_LINK.finditer(text):
            target = match.group(1)
            if re.match(r"^[a-z]+:", target):
                continue  # http:, https:, mailto:
            where = f"{page.relative_to(root)}:{text.count(chr(10), 0, match.start()) + 1}: {target}"
            path, _, fragment = target.partition("#")
            linked = (page.parent / path).resolve() if path else page
            if not linked.exists():
                problems.append(f"{where}: no such file")
            elif fragment and linked.suffix == ".md" and fragment not in heading_anchors(linked):
                problems.append(f"{where}: no heading #{fragment} there")
    return problems


CHECKS = {"layering": check_layering, "sizes": check_sizes, "links": check_links}


def main() -> int:
    if len(sys.argv) != 3 or sys.argv[1] not in CHECKS:
        print(__doc__, file=sys.stderr)
        return 2
    root = Path(sys.argv[2]).resolve()
    problems = CHECKS[sys.argv[1]](root)
    for problem in problems:
        print(problem)
    print(f"{sys.argv[1]}: {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
