// The video wall shows each tile's poster (its closing frame) and plays a tile only while
// the pointer is on it or it has the keyboard focus: dozens of videos playing at once are
// more than a browser decodes.
"use strict";
document.querySelectorAll("video.tile").forEach(function (video) {
  var play = function () {
    var started = video.play();
    if (started !== undefined) { started.catch(function () {}); }
  };
  var stop = function () { video.pause(); };
  video.addEventListener("mouseenter", play);
  video.addEventListener("focus", play);
  video.addEventListener("mouseleave", stop);
  video.addEventListener("blur", stop);
});
