"""The page's CSS: system fonts only, colours that survive printing."""

CSS = """
:root { --pass: #2e7d32; --fail: #c62828; --marginal: #b88600; --error: #6d1b7b;
        --invalid: #e65100; --info: #6b6b6b; --line: #d5d8dc; --soft: #f5f6f8; }
* { box-sizing: border-box; }
html { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", Arial,
       sans-serif; font-size: 14px; line-height: 1.4; color: #1b1f23; margin: 0 auto;
       padding: 16px 24px 40px; max-width: 1400px; }
h1 { font-size: 24px; margin: 2px 0 10px; }
h2 { font-size: 18px; margin: 28px 0 8px; padding-bottom: 4px; border-bottom: 2px solid
     var(--line); }
h3 { font-size: 14px; margin: 14px 0 6px; }
code, pre { font-family: ui-monospace, "DejaVu Sans Mono", Menlo, Consolas, monospace;
            font-size: 12px; }
pre { background: var(--soft); border: 1px solid var(--line); padding: 6px 8px;
      white-space: pre-wrap; word-break: break-word; margin: 4px 0; }
a { color: #0b57d0; }
.small { font-size: 12px; color: #555; }
.note { font-size: 12px; color: #7a4b00; background: #fff7e0; border-left: 3px solid #e0a800;
        padding: 3px 8px; margin: 4px 0; }
nav { font-size: 12px; margin-bottom: 12px; }
nav a { margin-right: 12px; }

.verdict { display: flex; align-items: stretch; gap: 20px; border-radius: 6px; padding: 16px 20px;
           border: 3px solid var(--vc); background: var(--vbg); }
.verdict-word { font-size: 46px; font-weight: 800; letter-spacing: 1px; color: #fff;
                background: var(--vc); border-radius: 4px; padding: 10px 22px;
                display: flex; align-items: center; white-space: nowrap; }
.verdict-body { flex: 1; }
.verdict-who { font-size: 16px; font-weight: 600; }
.v-pass { --vc: var(--pass); --vbg: #eef7ee; }
.v-fail { --vc: var(--fail); --vbg: #fdecec; }
.v-invalid-bench { --vc: var(--invalid); --vbg: #fff3e6; }
.v-error, .v-unknown { --vc: var(--error); --vbg: #f6ecf8; }
.chips { margin: 8px 0 4px; }
.chip { display: inline-block; margin-right: 8px; padding: 2px 10px; border-radius: 12px;
        background: #fff; border: 1px solid var(--line); font-size: 13px; }
.chip b { font-size: 16px; }
.c-pass b { color: var(--pass); } .c-fail b { color: var(--fail); }
.c-marginal b { color: var(--marginal); } .c-error b { color: var(--error); }
.c-info b { color: var(--info); }
.reasons { margin: 8px 0 0; padding-left: 20px; font-size: 13px; }

.cards { display: grid; grid-template-columns: 1fr 1fr; gap: 16px; }
.card { border: 1px solid var(--line); border-radius: 6px; padding: 6px 14px; }
.card h3 { margin-top: 6px; }
dl { display: grid; grid-template-columns: max-content 1fr; gap: 2px 14px; margin: 6px 0; }
dt { color: #555; } dd { margin: 0; word-break: break-all; }

table { border-collapse: collapse; width: 100%; font-size: 13px; }
th, td { border-bottom: 1px solid var(--line); padding: 4px 8px; text-align: left;
         vertical-align: top; }
thead th { background: #e9ecef; position: sticky; top: 0; }
tr.group th { background: var(--soft); font-weight: normal; padding-top: 8px; }
td code { overflow-wrap: break-word; }
td .num { font-variant-numeric: tabular-nums; font-weight: 600; }
table.measurements td:nth-child(3), table.measurements td:nth-child(5),
table.measurements td:nth-child(6) { text-align: right; font-variant-numeric: tabular-nums; }
tr.m-fail td, tr.t-failed td, tr.r-fail td { background: #fdecec; }
tr.m-fail td:first-child, tr.m-error td:first-child { border-left: 4px solid var(--fail); }
tr.m-error td, tr.t-error td, tr.r-error td { background: #f6ecf8; }
tr.m-marginal td { background: #fff8e1; }
tr.m-marginal td:first-child { border-left: 4px solid var(--marginal); }
tr.m-info td { color: #555; }
table.runs td:last-child a { margin-right: 8px; white-space: nowrap; }
table.runs td:nth-child(3), table.runs td:nth-child(4), table.runs td:nth-child(5),
table.tests td:nth-child(2), table.tests td:nth-child(3) { white-space: nowrap; }

.badge { display: inline-block; padding: 1px 7px; border-radius: 3px; font-size: 11px;
         font-weight: 700; color: #fff; background: var(--info); white-space: nowrap; }
.b-pass, .b-passed { background: var(--pass); }
.b-fail, .b-failed { background: var(--fail); }
.b-marginal { background: var(--marginal); }
.b-error, .b-aborted { background: var(--error); }
.b-invalid-bench { background: var(--invalid); }
.b-skipped, .b-info, .b-no-measurements { background: var(--info); }

.grid { display: grid; grid-template-columns: repeat(auto-fill, minmax(640px, 1fr));
        gap: 14px; align-items: start; }
figure { margin: 0; }
figure img { max-width: 100%; height: auto; display: block; border: 1px solid var(--line); }
figcaption, .figcap { font-size: 12px; margin-top: 4px; }
.mlist { margin: 2px 0; padding-left: 18px; }
.figure-missing { border: 1px dashed #c9a227; padding: 8px; border-radius: 4px; }
.lockstep { background: var(--soft); border: 1px solid var(--line); padding: 8px 12px; }

.signoff { margin-top: 36px; display: grid; grid-template-columns: repeat(3, 1fr); gap: 24px; }
.signoff div { border-top: 1px solid #333; padding-top: 4px; font-size: 12px; color: #555;
               margin-top: 40px; }
footer { margin-top: 24px; font-size: 11px; color: #777; }

@media print {
  body { max-width: none; padding: 0; font-size: 11px; }
  nav { display: none; }
  a { color: inherit; text-decoration: none; }
  h2 { break-after: avoid; }
  .verdict, figure, .plot, tr, .card, .figure-missing { break-inside: avoid; }
  thead th { position: static; }
  th, td { padding: 3px 5px; }
  .grid { grid-template-columns: 1fr; }
  figure img { max-width: 88%; }
  .verdict-word { font-size: 32px; }
  @page { size: A4; margin: 12mm; }
}
"""
