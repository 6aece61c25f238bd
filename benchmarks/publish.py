"""Where a benchmark's table goes: OUT/<name>.md, the terminal and, with --docs, the part of a
page of the project (docs/realdata.md, benchmarks/ASYNC_RESULTS.md, ...) between the markers
`<!-- benchmarks/<name>.py: begin -->` and `... end -->`."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def publish(lines: list[str], out: Path, name: str, docs_page: str | None = None) -> None:
    """Write `lines` to OUT/<name>.md and print them; with `docs_page` (e.g. "docs/realdata.md",
    relative to the checkout) replace that page's text between the benchmark's markers by them."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    if docs_page:
        begin, end = f"<!-- benchmarks/{name}.py: begin -->", f"<!-- benchmarks/{name}.py: end -->"
        docs = ROOT / docs_page
        page = docs.read_text()
        head, tail = page.split(begin)[0], page.split(end)[1]
        docs.write_text(head + begin + "\n" + "\n".join(lines) + "\n" + end + tail)
