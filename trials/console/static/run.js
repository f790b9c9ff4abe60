// The run page's script. While the run is driven live, or its log is being checked and played, ask the console how
// it stands every second and show it; once that has ended (and is recorded), reload the page, which then shows the
// outcome, or why there is none. A log form's button says that the upload is on its way while it is.
(function () {
  "use strict";

  function follow(box, show) {
    function poll() {
      fetch(box.dataset.url, {headers: {Accept: "application/json"}, cache: "no-store", credentials: "same-origin"})
        .then(function (response) {
          if (!response.ok) {
            throw new Error("HTTP " + response.status);
          }
          return response.json();
        })
        .then(function (now) {
          if (!now.running) {
            window.location.reload();
            return;
          }
          show(now);
          window.setTimeout(poll, 1000);
        })
        .catch(function (error) {
          show({problem: "no answer from the console (" + error.message + "); asking again"});
          window.setTimeout(poll, 2000);
        });
    }
    window.setTimeout(poll, 1000);
  }

  var live = document.getElementById("live");
  if (live && live.dataset.running === "1") {
    follow(live, function (now) {
      document.getElementById("live-detail").textContent = now.problem || now.detail || "";
      if (!now.problem) {
        document.getElementById("live-state").textContent = now.state || "starting";
        document.getElementById("live-since").textContent = now.since ? "since " + now.since : "";
      }
    });
  }

  var playing = document.getElementById("playing");
  if (playing && playing.dataset.running === "1") {
    follow(playing, function (now) {
      document.getElementById("playing-detail").textContent = now.problem || (now.log + ", since " + now.since);
    });
  }

  Array.prototype.forEach.call(document.querySelectorAll("form.log"), function (form) {
    form.addEventListener("submit", function () {
      var button = form.querySelector("button");
      // disabled after the form has gone, so that the button's own press still sends it
      window.setTimeout(function () {
        button.disabled = true;
        button.textContent = "Sending the log...";
      }, 0);
    });
  });
})();
