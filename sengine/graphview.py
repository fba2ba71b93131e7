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
    lines = [
        "digraph sengine {",
        "  rankdir=LR;",
        '  node [shape=box, style="rounded,filled", fillcolor="#eef3fb", fontname="Helvetica"];',
    ]
    for node, data in g.nodes(data=True):
        lines.append(f'  "{node}" [label="{node}\\n{data["type"]}"];')
    for u, v, data in g.edges(data=True):
        label = f"{data.get('src_port', '')} → {data.get('dst_port', '')}".strip(" →")
        lines.append(f'  "{u}" -> "{v}" [label="{label}", fontsize=10];')
    lines.append("}")
    return "\n".join(lines) + "\n"


LANE = 14  # px between the lanes of edges that skip columns


def layout(net: Network) -> tuple[dict[str, tuple[int, int]], list[tuple[list[tuple[int, int]], str]], int, int]:
    """Node boxes in columns by topological generation, and edge routes.

    Returns the top-left pixel of every node box, every edge as a polyline
    with its label (``src_port -> dst_port``), and the picture size.  An edge
    between neighbouring columns is straight; one that skips columns runs in
    its own lane above the boxes, so it never crosses a box.
    """
    g = net.graph()
    simple = nx.DiGraph(g)
    order = list(net.specs)
    try:
        generations = [sorted(gen, key=order.index) for gen in nx.topological_generations(simple)]
    except nx.NetworkXUnfeasible:  # a cycle: one column per node in file order
        generations = [[n] for n in order]
    column = {node: col for col, gen in enumerate(generations) for node in gen}
    edges = sorted(
        g.edges(data=True), key=lambda e: (column[e[1]] - column[e[0]], order.index(e[0]), order.index(e[1]))
    )
    long_edges = [e for e in edges if column[e[1]] - column[e[0]] != 1]
    top = MARGIN + LANE * len(long_edges)
    pos = {}
    for col, gen in enumerate(generations):
        for row, node in enumerate(gen):
            pos[node] = (MARGIN + col * (BOX_W + GAP_X), top + row * (BOX_H + GAP_Y))
    incoming: dict[str, int] = {}
    outgoing: dict[str, int] = {}
    routes = []
    lane = 0
    for u, v, data in edges:
        (x1, y1), (x2, y2) = pos[u], pos[v]
        k_out, k_in = outgoing.get(u, 0), incoming.get(v, 0)
        outgoing[u], incoming[v] = k_out + 1, k_in + 1
        label = f"{data.get('src_port', '')} -> {data.get('dst_port', '')}".strip(" ->")
        if column[v] - column[u] == 1:
            a = (x1 + BOX_W, y1 + 10 + (k_out * 9) % (BOX_H - 16))
            b = (x2, y2 + 10 + (k_in * 9) % (BOX_H - 16))
            routes.append(([a, (a[0] + GAP_X // 2, a[1]), (a[0] + GAP_X // 2, b[1]), b], label))
        else:
            lane += 1
            y = top - LANE * lane + LANE // 2
            a = (x1 + BOX_W - 12 - 6 * (k_out % 8), y1)
            b = (x2 + 12 + 6 * (k_in % 8), y2)
            routes.append(([a, (a[0], y), (b[0], y), b], label))
    width = MARGIN * 2 + max(1, len(generations)) * (BOX_W + GAP_X) - GAP_X
    height = top + MARGIN + max((len(gen) for gen in generations), default=1) * (BOX_H + GAP_Y) - GAP_Y
    return pos, routes, width, height


def _svg(net: Network) -> str:
    pos, routes, width, height = layout(net)
    g = net.graph()
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="Helvetica" font-size="12">',
        '<defs><marker id="a" markerWidth="8" markerHeight="8" refX="8" refY="4" orient="auto">'
        '<path d="M0,0 L8,4 L0,8 z" fill="#555"/></marker></defs>',
        f'<rect width="{width}" height="{height}" fill="white"/>',
    ]
    for points, label in routes:
        pts = " ".join(f"{x},{y}" for x, y in points)
        out.append(
            f'<polyline points="{pts}" fill="none" stroke="#667" marker-end="url(#a)"><title>{escape(label)}</title></polyline>'
        )
        (x, y) = points[1]
        out.append(f'<text x="{x + 3}" y="{y - 3}" font-size="9" fill="#556">{escape(label)}</text>')
    for node, (x, y) in pos.items():
        out.append(f'<rect x="{x}" y="{y}" width="{BOX_W}" height="{BOX_H}" rx="8" fill="#eef3fb" stroke="#3a5a8c"/>')
        out.append(
            f'<text x="{x + BOX_W // 2}" y="{y + 19}" text-anchor="middle" font-weight="bold">{escape(node)}</text>'
        )
        out.append(
            f'<text x="{x + BOX_W // 2}" y="{y + 36}" text-anchor="middle" fill="#445">'
            f"{escape(g.nodes[node]['type'])}</text>"
        )
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _png(net: Network, path: Path) -> None:
    from PIL import Image, ImageDraw

    pos, routes, width, height = layout(net)
    g = net.graph()
    img = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(img)
    for points, label in routes:
        draw.line(points, fill="#666677", width=1)
        (bx, by), (_, py) = points[-1], points[-2]
        if py == by:  # arrives from the left
            head = [(bx, by), (bx - 7, by - 4), (bx - 7, by + 4)]
        else:  # arrives from above
            head = [(bx, by), (bx - 4, by - 7), (bx + 4, by - 7)]
        draw.polygon(head, fill="#666677")
        x, y = points[1]
        draw.text((x + 3, y - 2), label, fill="#555566", anchor="ls")
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
        raise SEngineError(
            f"{path}: cannot draw a graph as {suffix or 'a file without suffix'!r}; use .dot, .svg or .png"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    if suffix in (".dot", ".gv"):
        tmp.write_text(to_dot(net))
    elif suffix == ".svg":
        tmp.write_text(_svg(net))
    else:
        _png(net, tmp)
    tmp.replace(path)
