"""The copy-a-command widget of the report pages (``report.html`` and the failure pages): a
command shown as code with a button that puts it on the clipboard, plus its CSS and script.

The script tries the Clipboard API and falls back to selecting a hidden text area and
``document.execCommand('copy')`` (pages opened from disk); the button then says whether it worked.
"""

from __future__ import annotations

import html

__all__ = ["command_html", "WIDGET_CSS", "WIDGET_JS"]


def command_html(command: str, note: str = "") -> str:
    """``command`` as code with a copy button, and ``note`` (where to run it, what may stop it)
    as small text below; HTML-escaped."""
    cmd = html.escape(command)
    out = (f'<span class="cf-cmd"><code>{cmd}</code><button type="button" class="cf-copy" data-copy="{cmd}" '
           f'title="copy the command">copy</button></span>')
    if note:
        out += f'<span class="cf-note">{html.escape(note)}</span>'
    return out


WIDGET_CSS = """
.cf-cmd { display: block; width: 36em; white-space: normal; margin-top: 2px; }
.cf-cmd code { word-break: break-all; font-size: 11.5px; background: #f3f4f7; padding: 1px 4px; }
button.cf-copy { font-size: 11px; padding: 0 6px; margin-left: 4px; cursor: pointer; border: 1px solid #b9c0cc;
                 border-radius: 3px; background: #fff; }
button.cf-copy.done { border-color: #2e8b57; color: #2e8b57; }
.cf-note { display: block; white-space: normal; width: 36em; font-size: 11.5px; color: #8a5a00; }
"""
"""CSS of :func:`command_html`."""

WIDGET_JS = r"""
(function () {
  function fallback(text) {
    var area = document.createElement('textarea');
    area.value = text; area.setAttribute('readonly', ''); area.style.position = 'fixed'; area.style.opacity = '0';
    document.body.appendChild(area); area.select();
    var ok = false;
    try { ok = document.execCommand('copy'); } catch (e) { ok = false; }
    document.body.removeChild(area);
    return ok;
  }
  function said(button, ok) {
    button.textContent = ok ? 'copied' : 'select and copy';
    button.classList.toggle('done', ok);
    setTimeout(function () { button.textContent = 'copy'; button.classList.remove('done'); }, 1500);
  }
  document.addEventListener('click', function (event) {
    var button = event.target.closest ? event.target.closest('button.cf-copy') : null;
    if (!button) return;
    var text = button.getAttribute('data-copy');
    if (navigator.clipboard && window.isSecureContext) {
      navigator.clipboard.writeText(text).then(function () { said(button, true); },
                                               function () { said(button, fallback(text)); });
    } else {
      said(button, fallback(text));
    }
  });
})();
"""
"""Script of :func:`command_html` (one click handler for the page)."""
