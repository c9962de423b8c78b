/*
 * Click-to-enlarge for the figures of the documentation.
 *
 * Every image of a figure or of the sphinx-gallery output that is not already a
 * link becomes a link to the image file itself, so that without JavaScript (or
 * with a middle click) it opens at full size. A plain click shows the image over
 * the page instead; a click anywhere or Escape closes it. No network access.
 */
(function () {
  "use strict";

  var SELECTOR = [
    ".bd-article figure img",
    ".bd-article img.sphx-glr-single-img",
    ".bd-article img.sphx-glr-multi-img",
    ".bd-article img.align-center",
    ".bd-article img.align-default",
  ].join(", ");

  function close(box) {
    if (box && box.parentNode) {
      box.parentNode.removeChild(box);
    }
    document.removeEventListener("keydown", onKey);
  }

  function onKey(event) {
    if (event.key === "Escape") {
      close(document.querySelector(".sk-lightbox"));
    }
  }

  function open(href, alt) {
    close(document.querySelector(".sk-lightbox"));
    var box = document.createElement("div");
    box.className = "sk-lightbox";
    box.setAttribute("role", "dialog");
    box.setAttribute("aria-label", alt || "Enlarged figure");
    var img = document.createElement("img");
    img.src = href;
    img.alt = alt || "";
    box.appendChild(img);
    box.addEventListener("click", function () {
      close(box);
    });
    document.addEventListener("keydown", onKey);
    document.body.appendChild(box);
  }

  function setUp() {
    document.querySelectorAll(SELECTOR).forEach(function (img) {
      if (img.closest("a, .sphx-glr-thumbcontainer")) {
        return; // already a link (:target: figures) or a gallery thumbnail
      }
      var link = document.createElement("a");
      link.href = img.currentSrc || img.src;
      link.className = "sk-zoom";
      link.title = "Click to enlarge";
      img.parentNode.insertBefore(link, img);
      link.appendChild(img);
      link.addEventListener("click", function (event) {
        if (event.button !== 0 || event.ctrlKey || event.metaKey || event.shiftKey) {
          return; // let the browser open a new tab or window
        }
        event.preventDefault();
        open(link.href, img.alt);
      });
    });
  }

  if (document.readyState === "loading") {
    document.addEventListener("DOMContentLoaded", setUp);
  } else {
    setUp();
  }
})();
