"""The results as JUnit XML (junit.xml: one test case per record); see
crosscheck.report.write."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from crosscheck.report.content import (
    Content,
    details,
    fmt,
    fmt_tol,
    machine_text,
    record_id,
    status,
    versions_of,
)

# ---- JUnit -----------------------------------------------------------------------------------


def render_junit(c: Content) -> str:
    """One <testsuite> per model, one <testcase> per record."""
    meta = c.results.get("meta") or {}
    root = ET.Element(
        "testsuites",
        name="crosscheck",
        tests=str(len(c.records)),
        failures=str(c.counts["fail"]),
        skipped=str(c.counts["skip"]),
        errors="0",
        time="0",
    )
    for m in dict.fromkeys(r.get("model", "?") for r in c.records):
        recs = c.records_of(m)
        suite = ET.SubElement(
            root,
            "testsuite",
            name=f"crosscheck.{m}",
            tests=str(len(recs)),
            failures=str(sum(status(r) == "fail" for r in recs)),
            skipped=str(sum(status(r) == "skip" for r in recs)),
            errors="0",
            time="0",
        )
        props = ET.SubElement(suite, "properties")
        ET.SubElement(props, "property", name="command", value=str(meta.get("command", "")))
        ET.SubElement(props, "property", name="machine", value=machine_text(meta))
        for k, v in versions_of(meta).items():
            ET.SubElement(props, "property", name=k, value=str(v))
        for r in recs:
            tc = ET.SubElement(
                suite,
                "testcase",
                classname=f"crosscheck.{m}.{r.get('engine', '?')}",
                name=f"{r.get('formulation', '?')}.{r.get('check', '?')}.{r.get('quantity', '?')}",
                time="0",
            )
            st = status(r)
            if st == "skip":
                ET.SubElement(tc, "skipped", message=str(r.get("reason") or "no reason given"))
            elif st == "fail":
                reason = str(r.get("reason") or "")
                f = ET.SubElement(
                    tc,
                    "failure",
                    type="ToleranceExceeded",
                    message=f"error {fmt(r.get('error'))} > tolerance "
                    f"{fmt_tol(r.get('tolerance'))}" + (f": {reason}" if reason else ""),
                )
                f.text = "\n".join(
                    x
                    for x in (
                        f"{record_id(r)}: error {r.get('error')!r}, tolerance "
                        f"{r.get('tolerance')!r}",
                        f"tolerance reason: {reason}" if reason else "",
                        details(r),
                    )
                    if x
                )
            elif details(r):
                ET.SubElement(tc, "system-out").text = details(r)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"
