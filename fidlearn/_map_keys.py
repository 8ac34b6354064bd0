"""A map's markers by key: each marker is (dictionary, id), its own size or the map's (:class:`_Keys`, a part of
:class:`fidlearn.MarkerMap`)."""

from __future__ import annotations

import numbers

from . import _cv
from ._map_parse import MarkerKey, MarkerPlacement
from .errors import MapError


class _Keys:
    """The marker keys, sizes and dictionaries of a :class:`fidlearn.MarkerMap` (its ``placements``,
    ``dictionary``, ``marker_size_mm`` and ``source``)."""

    placements: dict[int, MarkerPlacement]
    dictionary: str
    marker_size_mm: float
    source: str

    @property
    def dictionaries(self) -> list[str]:
        """The dictionaries the markers come from: the map's own first, then the others by name."""
        others = {p.dictionary for p in self.placements.values() if p.dictionary is not None}
        return [self.dictionary, *sorted(others - {self.dictionary})]

    def marker_size(self, marker_id: int) -> float:
        """One marker's black square side: its own ``size_mm``, else the map's ``marker_size_mm``.

        Parameters
        ----------
        marker_id : int or MarkerKey
            A marker of the map (a :class:`MarkerKey` for a marker of another dictionary than the map's).

        Returns
        -------
        float
            mm.

        Raises
        ------
        MapError
            If the map has no such marker.
        """
        return self._placement(marker_id).size_mm or self.marker_size_mm

    def marker_dictionary(self, marker_id: int) -> str:
        """One marker's dictionary: its own, else the map's.

        Parameters
        ----------
        marker_id : int or MarkerKey
            A marker of the map.

        Returns
        -------
        str
            The dictionary's name.

        Raises
        ------
        MapError
            If the map has no such marker.
        """
        return self._placement(marker_id).dictionary or self.dictionary

    def key(self, marker_id: int, dictionary: str | None = None) -> int:
        """The map's key of the marker ``marker_id`` of ``dictionary``: a marker is (dictionary, id).

        Parameters
        ----------
        marker_id : int or MarkerKey
            The id printed on the marker (a MarkerKey brings its dictionary).
        dictionary : str, optional
            Its dictionary; None: the map's.

        Returns
        -------
        int or MarkerKey
            The plain id for a marker of the map's dictionary, else ``MarkerKey(marker_id, dictionary)``; whether
            the map holds it is ``key in marker_map``.

        Raises
        ------
        MapError, DictionaryError
            An id that is not a whole number >= 0, or a dictionary OpenCV does not have.

        Examples
        --------
        >>> from fidlearn import MarkerMap
        >>> m = MarkerMap.from_dict({"units": "mm", "marker_size_mm": 80, "markers": {
        ...     "3": {"translation": [0, 0, 0]},
        ...     "4X4_50:3": {"translation": [0, 500, 0], "size_mm": 200}}})
        >>> m.key(3), m.key(3, "4X4_50"), m.marker_size(m.key(3, "DICT_4X4_50"))
        (3, 4X4_50:3, 200.0)
        """
        if isinstance(marker_id, bool) or not isinstance(marker_id, numbers.Integral) or marker_id < 0:
            raise MapError(f"{self.source}: a marker id is a whole number >= 0, got {marker_id!r:.40}")
        if dictionary is None and isinstance(marker_id, MarkerKey):
            dictionary = marker_id.dictionary
        if dictionary is None or dictionary == self.dictionary:
            return int(marker_id)
        name = _cv.dictionary_name(dictionary)
        return int(marker_id) if name == self.dictionary else MarkerKey(int(marker_id), name)

    def ids_in(self, dictionary: str) -> list[int]:
        """The plain ids of the map's markers of one dictionary.

        Parameters
        ----------
        dictionary : str
            A dictionary's name.

        Returns
        -------
        list of int
            Sorted.
        """
        name = _cv.dictionary_name(dictionary)
        return sorted(p.id for p in self.placements.values() if (p.dictionary or self.dictionary) == name)

    def _placement(self, marker_id: int) -> MarkerPlacement:
        if marker_id not in self.placements:
            raise MapError(f"{self.source}: no marker {marker_id} in the map; it has {list(self.placements)}")
        return self.placements[marker_id]
