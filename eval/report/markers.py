"""Replacing a generated block of a README: the lines between a start and an end marker (HTML
comments, invisible once rendered), and nothing else, so that the hand-written text around
the block survives every regeneration."""

from __future__ import annotations

from ipbench.eval.report.runs import DocsReportError

__all__ = ["replace_marked"]


def replace_marked(text: str, block: str, start: str, end: str, where: str, what: str) -> str:
    """``text`` with the lines between ``start`` and ``end`` replaced by ``block``; everything
    else, the markers and the line endings kept. ``where`` (the file) and ``what`` (the block,
    e.g. ``headline``) name them in the error.

    Raises
    ------
    DocsReportError
        When the markers are missing, repeated or out of order, saying which to add.
    """
    starts, ends = text.count(start), text.count(end)
    i, j = text.find(start), text.find(end)
    if starts != 1 or ends != 1 or j < i:
        problem = (
            f"has no {what} markers"
            if starts == ends == 0
            else f"has {starts} start and {ends} end marker(s)"
            if starts != 1 or ends != 1
            else "has the end marker before the start marker"
        )
        raise DocsReportError(
            f"{where} {problem}; put the two lines\n  {start}\n  {end}\nonce where the {what} "
            "table goes (the text between them is replaced)"
        )
    newline = "\r\n" if "\r\n" in text else "\n"
    body = block if block.endswith("\n") else block + "\n"
    return text[: i + len(start)] + newline + body.replace("\n", newline) + text[j:]
