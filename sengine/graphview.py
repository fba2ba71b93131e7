"""Draw a network: Graphviz ``.dot`` text, or a layered ``.svg`` / ``.png``.

The pictures need neither Graphviz nor matplotlib: nodes are laid out in
columns by topological generation (networkx) and drawn with plain SVG or
Pillow, so ``sengine graph`` works on any machine.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape

import networkx as nx

from .errors import SEngineError
from .network import Network

__all__ = ["to_dot", "layout", "write_graph"]

BOX_W, BOX_H, GAP_X, GAP_Y, MARGIN = 190, 46, 80, 26, 20


def to_dot(net: Network) -> str:
    """The network as Graphviz text (left to right, ports on the edges)."""
    g = net.graph()
    lines = ["digraph sengine {", "  rankdir=LR;", '  node [shape=box, style="rounded,filled", fillcolor="#eef3fb", fontname="Helvetica"];']
    for node, data in g.nodes(data=True):
        lines.append(f'  "{node}" [label="{node}\\n{data["type"]}"];')
    for u, v, data in g.edges(data=True):
        label = f'{data.get("src_port", "")} → {data.get("dst_port", "")}'.strip(" →")
        lines.append(f'  "{u}" -> "{v}" [label="{label}", fontsize=10];')
    lines.append("}")
    return "\n".join(lines) + "\n"


def layout(net: Network) -> tuple[dict[str, tuple[int, int]], int, int]:
    """Top-left pixel position of every node box, and the picture size."""
    g = net.graph()
    simple = nx.DiGraph(g)
    try:
        generations = [sorted(gen, key=list(net.specs).index) for gen in nx.topological_generations(simple)]
    except nx.NetworkXUnfeasible:  # a cycle: one column per node in file order
        generations = [[n] for n in net.specs]
    pos = {}
    for col, gen in enumerate(generations):
        for row, node in enumerate(gen):
            pos[node] = (MARGIN + col * (BOX_W + GAP_X), MARGIN + row * (BOX_H + GAP_Y))
    width = MARGIN * 2 + max(1, len(generations)) * (BOX_W + GAP_X) - GAP_X
    height = MARGIN * 2 + max((len(g) for g in generations), default=1) * (BOX_H + GAP_Y) - GAP_Y
    return pos, width, height


def _svg(net: Network) -> str:
    pos, width, height = layout(net)
    g = net.graph()
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="Helvetica" font-size="12">',
           '<defs><marker id="a" markerWidth="8" markerHeight="8" refX="8" refY="4" orient="auto">'
           '<path d="M0,0 L8,4 L0,8 z" fill="#555"/></marker></defs>',
           f'<rect width="{width}" height="{height}" fill="white"/>']
    for u, v, data in g.edges(data=True):
        (x1, y1), (x2, y2) = pos[u], pos[v]
        a, b = (x1 + BOX_W, y1 + BOX_H // 2), (x2, y2 + BOX_H // 2)
        out.append(f'<line x1="{a[0]}" y1="{a[1]}" x2="{b[0]}" y2="{b[1]}" stroke="#555" marker-end="url(#a)"/>')
        label = escape(data.get("dst_port", ""))
        out.append(f'<text x="{b[0] - 4}" y="{b[1] - 4}" text-anchor="end" font-size="10" fill="#555">{label}</text>')
    for node, (x, y) in pos.items():
        out.append(f'<rect x="{x}" y="{y}" width="{BOX_W}" height="{BOX_H}" rx="8" fill="#eef3fb" stroke="#3a5a8c"/>')
        out.append(f'<text x="{x + BOX_W // 2}" y="{y + 19}" text-anchor="middle" font-weight="bold">{escape(node)}</text>')
        out.append(f'<text x="{x + BOX_W // 2}" y="{y + 36}" text-anchor="middle" fill="#445">'
                   f'{escape(g.nodes[node]["type"])}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _png(net: Network, path: Path) -> None:
    from PIL import Image, ImageDraw

    pos, width, height = layout(net)
    g = net.graph()
    img = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(img)
    for u, v, data in g.edges(data=True):
        (x1, y1), (x2, y2) = pos[u], pos[v]
        a, b = (x1 + BOX_W, y1 + BOX_H // 2), (x2, y2 + BOX_H // 2)
        draw.line([a, b], fill="#555555", width=2)
        draw.polygon([b, (b[0] - 9, b[1] - 5), (b[0] - 9, b[1] + 5)], fill="#555555")
        draw.text((b[0] - 6, b[1] - 14), data.get("dst_port", ""), fill="#555555", anchor="rs")
    for node, (x, y) in pos.items():
        draw.rounded_rectangle([x, y, x + BOX_W, y + BOX_H], radius=8, fill="#eef3fb", outline="#3a5a8c", width=2)
        draw.text((x + BOX_W // 2, y + 16), node, fill="black", anchor="mm")
        draw.text((x + BOX_W // 2, y + 32), g.nodes[node]["type"], fill="#444455", anchor="mm")
    img.save(path, format="PNG")


def write_graph(net: Network, path: Path) -> None:
    """Write the network picture; the format follows the file's suffix."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".dot", ".gv", ".svg", ".png"):
        raise SEngineError(f"{path}: cannot draw a graph as {suffix or 'a file without suffix'!r}; "
                           "use .dot, .svg or .png")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    if suffix in (".dot", ".gv"):
        tmp.write_text(to_dot(net))
    elif suffix == ".svg":
        tmp.write_text(_svg(net))
    else:
        _png(net, tmp)
    tmp.replace(path)
