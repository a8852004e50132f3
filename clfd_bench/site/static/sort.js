// Sorts a table.sortable by the clicked column: numbers by value (empty cells last), text
// alphabetically. The first click on a column puts its best values first: a header's
// data-better ("higher" or "lower", from the glossary) says which way is better; without
// it, ascending. A click on the column already sorted reverses it.
"use strict";
document.querySelectorAll("table.sortable").forEach(function (table) {
  var heads = table.tHead.rows[table.tHead.rows.length - 1].cells;
  Array.prototype.forEach.call(heads, function (th, col) {
    th.classList.add("sort");
    th.tabIndex = 0;
    var sort = function () {
      var numeric = th.dataset.type === "number";
      var current = th.getAttribute("aria-sort");
      var dir;
      if (current) {
        dir = current === "ascending" ? -1 : 1;
      } else {
        dir = th.dataset.better === "higher" ? -1 : 1;
      }
      var body = table.tBodies[0];
      var rows = Array.prototype.slice.call(body.rows);
      var key = function (row) {
        var v = row.cells[col].dataset.sort;
        if (v === undefined) { v = row.cells[col].textContent.trim(); }
        return numeric ? (v === "" ? NaN : parseFloat(v)) : v.toLowerCase();
      };
      rows.sort(function (a, b) {
        var x = key(a), y = key(b);
        if (numeric) {
          if (isNaN(x) || isNaN(y)) { return isNaN(x) - isNaN(y); }
          return dir * (x - y);
        }
        return dir * x.localeCompare(y);
      });
      rows.forEach(function (row) { body.appendChild(row); });
      Array.prototype.forEach.call(heads, function (h) { h.removeAttribute("aria-sort"); });
      th.setAttribute("aria-sort", dir === 1 ? "ascending" : "descending");
    };
    th.addEventListener("click", sort);
    th.addEventListener("keydown", function (e) { if (e.key === "Enter") { sort(); } });
  });
});
