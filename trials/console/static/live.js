// The run page's live state: while the run is live, ask the console for it every second and show it; when the run
// has ended (and its ending is recorded), reload the page, which then shows the outcome or why it was aborted.
(function () {
  "use strict";
  var box = document.getElementById("live");
  if (!box || box.dataset.running !== "1") {
    return;
  }
  var state = document.getElementById("live-state");
  var detail = document.getElementById("live-detail");

  function poll() {
    fetch(box.dataset.url, {headers: {Accept: "application/json"}, cache: "no-store", credentials: "same-origin"})
      .then(function (response) {
        if (!response.ok) {
          throw new Error("HTTP " + response.status);
        }
        return response.json();
      })
      .then(function (live) {
        if (!live.running) {
          window.location.reload();
          return;
        }
        state.textContent = live.state || "starting";
        detail.textContent = live.detail || "";
        window.setTimeout(poll, 1000);
      })
      .catch(function (error) {
        detail.textContent = "no answer from the console (" + error.message + "); asking again";
        window.setTimeout(poll, 2000);
      });
  }

  window.setTimeout(poll, 1000);
})();
