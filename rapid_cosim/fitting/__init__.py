"""From experiments to scores: ``problem`` (the search space and which dimension sets
which FMU parameter), ``fitness`` (RSSD, ARSSD, the whitened fitness), ``objective``
(many parameter sets scored, through an engine), ``engine`` (where batches run: this
process, local workers or a dask cluster), ``search`` (the box and a batch's scores: a
leaf the estimators share)."""
