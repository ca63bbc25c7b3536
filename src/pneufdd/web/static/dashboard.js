// pneufdd dashboard: live parts refreshed on server-sent events; writes carry the CSRF token.
// Plain browser APIs (EventSource, fetch) and plotly.js; no framework.
"use strict";
function csrfToken() {
  const found = document.cookie.split("; ").find((c) => c.startsWith("csrftoken="));
  return found ? decodeURIComponent(found.slice("csrftoken=".length)) : "";
}
async function post(url, body) {
  const response = await fetch(url, {
    method: "POST", credentials: "same-origin",
    headers: {"content-type": "application/json", "x-csrftoken": csrfToken()},
    body: JSON.stringify(body || {}),
  });
  return response;
}
async function drawFigures() {
  const urls = new Map();
  for (const el of document.querySelectorAll("[data-figures]")) {
    const url = el.dataset.figures;
    if (!urls.has(url)) urls.set(url, fetch(url, {credentials: "same-origin"}).then((r) => r.json()));
    const figures = await urls.get(url);
    const fig = figures[el.dataset.key];
    if (fig && window.Plotly) Plotly.react(el, fig.data, fig.layout, {displaylogo: false, responsive: true});
  }
  const inline = document.getElementById("statistic-figure");
  if (inline && window.Plotly) {
    const fig = JSON.parse(inline.textContent);
    Plotly.react("statistic", fig.data, fig.layout, {displaylogo: false, responsive: true});
  }
}
async function refresh() {
  for (const el of document.querySelectorAll("[data-fragment]")) {
    const response = await fetch(el.dataset.fragment, {credentials: "same-origin"});
    if (response.ok) el.innerHTML = await response.text();
  }
  await drawFigures();
  document.body.dataset.refreshed = String(Date.now());
}
function listen() {
  const live = document.getElementById("live");
  const source = new EventSource("/events");
  source.addEventListener("hello", () => { live.textContent = "live updates: on"; live.classList.add("on"); });
  source.addEventListener("change", () => refresh());
  source.onerror = () => { live.textContent = "live updates: reconnecting"; live.classList.remove("on"); };
}
document.addEventListener("click", async (event) => {
  const button = event.target.closest("button[data-post]");
  if (button) {
    button.disabled = true;
    const body = button.dataset.location ? {location: button.dataset.location} : {};
    const response = await post(button.dataset.post, body);
    if (!response.ok) button.textContent = "refused (" + response.status + ")";
    await refresh();
    return;
  }
  if (event.target.closest("button[data-logout]")) {
    await post("/logout");
    window.location.href = "/login";
  }
});
const form = document.getElementById("login");
if (form) {
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const data = Object.fromEntries(new FormData(form).entries());
    const response = await post("/login", data);
    if (response.ok) window.location.href = "/";
    else document.getElementById("login-error").textContent = "not recognised";
  });
} else {
  listen();
  drawFigures();
}
