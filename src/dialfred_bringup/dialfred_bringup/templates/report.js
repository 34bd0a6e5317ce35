(function () {
  'use strict';
  var typeSelect = document.getElementById('filter-type');
  var outcomeSelect = document.getElementById('filter-outcome');
  var shownCount = document.getElementById('shown-count');
  var noneShown = document.getElementById('none-shown');
  var episodes = Array.prototype.slice.call(document.querySelectorAll('article.episode'));

  function matches(episode, type, outcome) {
    if (type !== 'all' && episode.dataset.type !== type) { return false; }
    if (outcome === 'all') { return true; }
    if (outcome === 'success' || outcome === 'failure') { return episode.dataset.outcome === outcome; }
    return episode.dataset.outcome === 'failure' && 'failure:' + episode.dataset.reason === outcome;
  }

  function hasOption(select, value) {
    return Array.prototype.some.call(select.options, function (o) { return o.value === value; });
  }

  function apply() {
    var type = typeSelect.value, outcome = outcomeSelect.value, shown = 0;
    episodes.forEach(function (episode) {
      var show = matches(episode, type, outcome);
      episode.hidden = !show;
      if (show) { shown += 1; }
    });
    shownCount.textContent = String(shown);
    noneShown.hidden = shown !== 0;
    var params = new URLSearchParams();
    if (type !== 'all') { params.set('type', type); }
    if (outcome !== 'all') { params.set('outcome', outcome); }
    var fragment = params.toString();
    if (fragment !== location.hash.replace(/^#/, '')) {
      try { history.replaceState(null, '', fragment ? '#' + fragment : location.pathname + location.search); }
      catch (e) { /* some browsers refuse history on file: pages; the filter still works */ }
    }
  }

  function fromFragment() {
    var params = new URLSearchParams(location.hash.replace(/^#/, ''));
    var type = params.get('type') || 'all', outcome = params.get('outcome') || 'all';
    typeSelect.value = hasOption(typeSelect, type) ? type : 'all';
    outcomeSelect.value = hasOption(outcomeSelect, outcome) ? outcome : 'all';
  }

  function filterType(type) {
    typeSelect.value = hasOption(typeSelect, type) ? type : 'all';
    apply();
    document.getElementById('episodes').scrollIntoView();
  }

  typeSelect.addEventListener('change', apply);
  outcomeSelect.addEventListener('change', apply);
  document.getElementById('filter-reset').addEventListener('click', function () {
    typeSelect.value = 'all';
    outcomeSelect.value = 'all';
    apply();
  });
  Array.prototype.forEach.call(document.querySelectorAll('[data-filter-type]'), function (row) {
    row.addEventListener('click', function () { filterType(row.dataset.filterType); });
    row.addEventListener('keydown', function (event) {
      if (event.key === 'Enter' || event.key === ' ') { event.preventDefault(); filterType(row.dataset.filterType); }
    });
  });
  window.addEventListener('hashchange', function () { fromFragment(); apply(); });
  fromFragment();
  apply();
  document.body.dataset.ready = 'true';
})();
