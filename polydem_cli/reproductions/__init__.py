"""The reproductions of the three sources, each comparing polydem's results with the source's numbers
(:mod:`.sources`, data files citing their sections and tables): Schneider (2012) chapters 5 and 7
(:mod:`.ch5`, :mod:`.ch7`) and the integrators of its appendix (:mod:`.integrators`), Luding & Herrmann's
biaxial box (:mod:`.lh`), Sorg's adaptive coupling (:mod:`.coupling`); the figure index and the generated
blocks of the docs (:mod:`.index`, :mod:`.docs`)."""
