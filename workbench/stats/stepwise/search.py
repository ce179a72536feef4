"""One stepwise search with MATLAB ``stepwiselm``'s rules on the swept cross-product matrix
(see :func:`~workbench.stats.stepwise`, Notes), and the :class:`StepwiseFit` it ends in."""

from __future__ import annotations

import math

import numpy as np
from scipy import special as _special

from ..design import Encoding
from .layout import _eligible_terms, _model_labels, _removable_terms
from .result import StepwiseFit
from .sweep import COLLINEARITY_TOLERANCE, _Problem, _problem, _sweep

#: A model fits exactly (zero noise up to round-off) when its SSE is at most this fraction
#: of the total sum of squares; no term is added after that, since every F-test would
#: compare round-off with round-off.
EXACT_FIT_TOLERANCE = 1e-12

#: Default step limit per term of the upper model (intercept included): the second guard
#: after the cycle guard (a search that never repeats a model ends within 2**m steps anyway,
#: but a legitimate search takes at most a few steps per term).
STEPS_PER_TERM = 4


def default_step_limit(n_terms: int) -> int:
    """Steps a search over an upper model of *n_terms* terms takes at most by default."""
    return STEPS_PER_TERM * max(int(n_terms), 1) + 10


def _f_sf(f: np.ndarray | float, df_num: float, df_den: float) -> np.ndarray:
    """Upper tail P(F > f) of the F(df_num, df_den) distribution."""
    return _special.fdtrc(df_num, df_den, f)


class _Search:
    """State of one stepwise search (see :func:`stepwise`, Notes)."""

    def __init__(
        self, *, candidates, y, finite, layout, criterion, p_enter, p_remove, response_name="y"
    ):
        self.candidates = candidates
        self.response_name = response_name
        self.y = y
        self.finite = finite  # None: no NaN in any used predictor
        self.layout = layout
        self.criterion = criterion
        self.p_enter, self.p_remove = p_enter, p_remove
        negated = criterion in ("rsquared", "adjrsquared")
        # every score is "smaller is better for adding": R² gains are negated
        self.enter_threshold = -p_enter if negated else p_enter
        self.remove_threshold = -p_remove if negated else p_remove
        self.y_slot = candidates.shape[1]
        self.problems: dict[bytes | None, tuple[_Problem, np.ndarray | None]] = {}
        self.steps: list[tuple] = []
        self.skipped: dict[tuple[str, str], int] = {}
        self.model: list[int] = []
        self.swept: dict[int, list[int]] = {}  # term -> its columns swept into the model
        self._columns_cache: list[int] | None = None
        self.warnings: list[str] = []

    # ----------------------------------------------------------------- row sets
    def _rows(self, terms) -> np.ndarray | None:
        if self.finite is None:
            return None
        columns = sorted({c for t in terms for c in self.layout.predictors[t]})
        if not columns:
            return np.ones(self.finite.shape[0], dtype=bool)
        return self.finite[:, columns].all(axis=1)

    def _problem_for(self, rows: np.ndarray | None) -> _Problem:
        key = None if rows is None or rows.all() else rows.tobytes()
        if key not in self.problems:
            if key is None:
                problem = _problem(self.candidates, self.y)
            else:
                problem = _problem(self.candidates[rows], self.y[rows])
            self.problems[key] = (problem, rows)
        return self.problems[key][0]

    def _swept_matrix(self, problem: _Problem, model_columns) -> tuple[np.ndarray, int]:
        matrix = problem.cross.copy()
        count = 0
        for column in model_columns:
            if matrix[column, column] > COLLINEARITY_TOLERANCE:
                _sweep(matrix, column)
                count += 1
        return matrix, count

    def _model_columns(self) -> list[int]:
        if self._columns_cache is None:
            self._columns_cache = [c for t in self.model for c in self.swept.get(t, [])]
        return self._columns_cache

    # ----------------------------------------------------------------- statistics
    def _score_add(self, n, k, sse, sst, decrease, df):
        """F, p and score of adding terms with SSE decrease *decrease* and *df* columns."""
        dfe_new = n - k - df
        sse_new = np.maximum(sse - decrease, 0.0)
        # decrease / 1.0 is decrease: one division less for one-column candidates
        f_stat = (decrease if isinstance(df, float) and df == 1.0 else decrease / df) / (
            sse_new / dfe_new
        )
        p_value = _f_sf(f_stat, df, dfe_new)
        criterion = self.criterion
        if criterion == "sse":
            score = p_value
            value = p_value  # not recorded for "sse"
        elif criterion in ("aic", "bic"):
            penalty = 2.0 if criterion == "aic" else np.log(n)
            score = n * np.log(sse_new / sse) + penalty * df
            value = n * (np.log(2 * np.pi * sse_new / n) + 1.0) + penalty * (k + df)
        elif criterion == "rsquared":
            value = 1.0 - sse_new / sst
            score = -(decrease / sst)
        else:
            value = 1.0 - (sse_new / dfe_new) / (sst / (n - 1))
            score = -(value - (1.0 - (sse / (n - k)) / (sst / (n - 1))))
        return f_stat, p_value, score, value

    def _gains(self, matrix: np.ndarray, terms: np.ndarray):
        """SSE decrease, degrees of freedom and columns of adding each term to the model
        swept into *matrix* (collinear columns of a term are left out). Degrees of freedom
        None: every term one column, none collinear; columns None: each term's one column."""
        layout = self.layout
        y = self.y_slot
        if layout.single:
            index = layout.first_column[terms]
            unexplained = matrix[index, index]
            ok = unexplained > COLLINEARITY_TOLERANCE
            if ok.all():  # df None: one column each, none collinear
                return matrix[index, y] ** 2 / unexplained, None, None
            decrease = np.zeros(len(terms))
            df = np.zeros(len(terms))
            decrease[ok] = matrix[index[ok], y] ** 2 / unexplained[ok]
            df[ok] = 1.0
            return decrease, df, None  # columns: the term's one column
        decrease = np.zeros(len(terms))
        df = np.zeros(len(terms))
        columns: list[list[int]] = []
        for position, term in enumerate(terms):
            cols = [int(c) for c in layout.columns[term]]
            if len(cols) == 1:
                u = matrix[cols[0], cols[0]]
                if u > COLLINEARITY_TOLERANCE:
                    decrease[position] = matrix[cols[0], y] ** 2 / u
                    df[position] = 1.0
                    columns.append(cols)
                else:
                    columns.append([])
                continue
            index = [*cols, y]
            small = matrix[np.ix_(index, index)].copy()
            kept = []
            for j in range(len(cols)):
                if small[j, j] > COLLINEARITY_TOLERANCE:
                    _sweep(small, j)
                    kept.append(cols[j])
            decrease[position] = matrix[y, y] - small[-1, -1]
            df[position] = len(kept)
            columns.append(kept)
        return decrease, df, columns

    def _sweep_model(self, *, start: bool):
        """The rows, problem and swept cross-product matrix of :attr:`model` on its own rows
        (MATLAB's per-candidate rule), recording each term's swept columns in
        :attr:`swept`; a *start* model with a term collinear with those before it is
        refused."""
        layout = self.layout
        rows = self._rows(self.model)
        problem = self._problem_for(rows)
        matrix = problem.cross.copy()
        for term in self.model:
            if layout.is_intercept[term]:
                continue
            kept = []
            for column in layout.columns[term]:
                if matrix[column, column] > COLLINEARITY_TOLERANCE:
                    _sweep(matrix, int(column))
                    kept.append(int(column))
            if start and not kept:
                raise ValueError(
                    f"start model is rank deficient: term {layout.display[term]!r} is collinear "
                    "with the terms before it"
                )
            self.swept[term] = kept
        self._columns_cache = None
        return rows, problem, matrix

    # ----------------------------------------------------------------- the search
    def run(self, start: list[int], lower: set[int], max_steps: int | None) -> None:
        layout = self.layout
        display = layout.display
        n_terms = len(layout.terms)
        self.model = sorted(start)
        rows, problem, matrix = self._sweep_model(start=True)
        protected = frozenset(int(t) for t in lower)
        just_added = just_removed = -1
        step = 0
        limit = default_step_limit(n_terms) if max_steps is None else max_steps
        # cycle guard: the models visited (sorted term indices), in order
        history = [tuple(self.model)]
        visited = {history[0]: 0}
        while step < limit:
            k = 1 + len(self._model_columns())
            n = problem.n
            dfe = n - k
            sse = max(float(matrix[self.y_slot, self.y_slot]), 0.0)
            sst = problem.sst
            acted = False

            # ---- try to add: not in the model, hierarchy satisfied, not just removed
            model_key = tuple(self.model)
            eligible_index = _eligible_terms(layout, model_key, just_removed)
            exact = sse <= EXACT_FIT_TOLERANCE * sst
            if eligible_index.size and exact:
                reason = (
                    f"exact fit: SSE/SST <= {EXACT_FIT_TOLERANCE:g} (round-off), "
                    "F-tests are meaningless"
                )
                for index in eligible_index.tolist():
                    self.skipped.setdefault((display[index], reason), step + 1)
            elif eligible_index.size:
                best = self._best_addition(eligible_index, matrix, problem, rows, step)
                if best is not None:
                    index, record, columns, new_rows = best
                    if record[0] < self.enter_threshold:
                        self.steps.append((step + 1, "add", display[index], *record[1:]))
                        self.model = sorted([*self.model, index])
                        self.swept[index] = columns
                        self._columns_cache = None
                        if new_rows is not None and not np.array_equal(new_rows, rows):
                            rows = new_rows
                            problem = self._problem_for(rows)
                            matrix, _ = self._swept_matrix(problem, self._model_columns())
                        else:
                            for column in columns:
                                _sweep(matrix, column)
                        just_added, just_removed = index, -1
                        acted = True

            # ---- otherwise try to remove: not protected, not just added, no child in model
            if not acted and dfe >= 1:
                terms, removable = _removable_terms(layout, model_key, protected, just_added)
                if removable.any():
                    worst = self._worst_removal(terms, removable, matrix, n, k, sse, sst)
                    if worst is not None and worst[1][0] > self.remove_threshold:
                        index, record = worst
                        self.steps.append((step + 1, "remove", display[index], *record[1:]))
                        self.model = [t for t in self.model if t != index]
                        self.swept.pop(index, None)
                        self._columns_cache = None
                        rows = self._rows(self.model)
                        problem = self._problem_for(rows)
                        # afresh: no drift from sweeping back
                        matrix, _ = self._swept_matrix(problem, self._model_columns())
                        just_added, just_removed = -1, index
                        acted = True
            if not acted:
                break
            step += 1
            key = tuple(self.model)
            first = visited.get(key)
            if first is not None:
                problem, matrix, rows = self._stop_in_cycle(history[first:], first, step)
                break
            visited[key] = len(history)
            history.append(key)
        else:
            if max_steps is None and step >= limit:
                self.warnings.append(
                    f"{self.response_name}: stepwise search stopped at the default step limit "
                    f"({limit} steps for {n_terms} terms) before it converged; the model after "
                    f"step {step} is reported"
                )
        self.final = (problem, matrix, rows)

    # ----------------------------------------------------------------- cycle guard
    def _model_score(self, model, problem) -> tuple[float, float, float, float, int, int]:
        """(score, criterion value, f_stat, p_value, df, n) of *model* fitted on *problem*'s
        rows; a smaller score is better by the criterion (see :meth:`_stop_in_cycle`)."""
        layout = self.layout
        columns = [int(c) for t in model if not layout.is_intercept[t] for c in layout.columns[t]]
        matrix, swept = self._swept_matrix(problem, columns)
        n, k = problem.n, 1 + swept
        sse = max(float(matrix[self.y_slot, self.y_slot]), 0.0)
        sst = problem.sst
        dfe = n - k
        if dfe < 1 or not sst > 0:
            return math.inf, math.nan, math.nan, math.nan, swept, n
        if swept:
            f_stat = ((sst - sse) / swept) / (sse / dfe) if sse > 0 else math.inf
            p_value = float(_f_sf(f_stat, swept, dfe))
        else:
            f_stat = p_value = math.nan
        criterion = self.criterion
        if criterion == "sse":
            # the model's F-test against the constant model; the constant model scores
            # p_enter, so a larger model is kept only when it is significant at p_enter
            score = value = self.p_enter if not swept else p_value
        elif criterion in ("aic", "bic"):
            penalty = 2.0 if criterion == "aic" else math.log(n)
            value = n * (math.log(2 * math.pi * max(sse, 1e-300) / n) + 1.0) + penalty * k
            score = value
        elif criterion == "rsquared":
            value = 1.0 - sse / sst
            score = -value
        else:
            value = 1.0 - (sse / dfe) / (sst / (n - 1))
            score = -value
        return float(score), float(value), float(f_stat), float(p_value), swept, n

    def _stop_in_cycle(self, cycle, first_step: int, step: int):
        """Stop a search that returned to a model it visited (at *first_step*): keep the
        best model of the cycle by the criterion, every model of the cycle fitted on one
        sample, the rows complete in the variables of all of them. Returns the kept model's
        (problem, swept matrix, rows) on its own rows and records the stop in the step log
        and the warnings.

        Scores: ``"sse"`` the p-value of the model's F-test against the constant model (the
        constant model scores *p_enter*), ``"aic"``/``"bic"`` the criterion, ``"rsquared"``
        and ``"adjrsquared"`` the (adjusted) R²; ties go to the smaller model, then the one
        visited first.
        """
        layout = self.layout
        union = sorted({t for model in cycle for t in model})
        common_rows = self._rows(union)
        common = self._problem_for(common_rows)
        scored = []
        for position, model in enumerate(cycle):
            score, value, f_stat, p_value, df, n = self._model_score(model, common)
            scored.append(((score, len(model), position), model, value, f_stat, p_value, df, n))
        scored.sort(key=lambda item: item[0])
        _, best, value, f_stat, p_value, df, n = scored[0]

        # the kept model on its own rows (MATLAB's per-candidate rule)
        self.model = list(best)
        self.swept = {}
        rows, problem, matrix = self._sweep_model(start=False)

        def formula(model) -> str:
            terms = [layout.display[t] for t in model if not layout.is_intercept[t]]
            return " + ".join(["1", *terms])

        models = " -> ".join(formula(model) for model in [*cycle, cycle[0]])
        kept_model = formula(best)
        record = [f_stat, p_value]
        if self.criterion != "sse":
            record += [value, math.nan]
        self.steps.append((step + 1, "stop", kept_model, *record, int(df), int(n)))
        self.warnings.append(
            f"{self.response_name}: stepwise search cycled (step {step} returned to the model "
            f"after step {first_step}: {models}); stopped at the best "
            f"model of the cycle by the {self.criterion} criterion, each fitted on the {n} "
            f"rows complete in the cycle's variables: {self.response_name} ~ {kept_model}"
        )
        return problem, matrix, rows

    def _best_addition(self, eligible_index, matrix, problem, rows, step):
        """Best candidate: (term, record, columns, rows) or None when none is testable."""
        display = self.layout.display
        groups: dict[bytes | None, list[int]] = {}
        group_rows: dict[bytes | None, np.ndarray | None] = {}
        if self.finite is None:
            groups[None] = eligible_index
            group_rows[None] = None
        else:
            for term in eligible_index.tolist():
                candidate_rows = self._rows([*self.model, term])
                key = None if np.array_equal(candidate_rows, rows) else candidate_rows.tobytes()
                groups.setdefault(key, []).append(term)
                group_rows[key] = rows if key is None else candidate_rows
        k = 1 + len(self._model_columns())
        best = None
        for key, terms in groups.items():
            if key is None:
                group_problem, group_matrix, group_k = problem, matrix, k
            else:
                candidate_rows = group_rows[key]
                if candidate_rows.sum() < 2:
                    for term in terms:
                        self.skipped.setdefault(
                            (display[term], "no complete rows with the model's variables"),
                            step + 1,
                        )
                    continue
                group_problem = self._problem_for(candidate_rows)
                group_matrix, swept = self._swept_matrix(group_problem, self._model_columns())
                group_k = 1 + swept
            terms_array = np.asarray(terms)
            n = group_problem.n
            sse = max(float(group_matrix[self.y_slot, self.y_slot]), 0.0)
            decrease, df, columns = self._gains(group_matrix, terms_array)
            if df is None:  # one column each, none collinear: every test has one dfe
                df = 1.0
                if n - group_k - 1 < 1:
                    reason = f"too few observations: n={n} leaves no error degrees of freedom"
                    for term in terms_array.tolist():
                        self.skipped.setdefault((display[term], reason), step + 1)
                    continue
                ok = None
            else:
                collinear = df == 0
                short = ~collinear & (n - group_k - df < 1)
                ok = ~collinear & ~short
            if ok is not None and not ok.all():
                for term in terms_array[collinear].tolist():
                    self.skipped.setdefault(
                        (display[term], "collinear with the model's terms"), step + 1
                    )
                for term in terms_array[short].tolist():
                    reason = f"too few observations: n={n} leaves no error degrees of freedom"
                    self.skipped.setdefault((display[term], reason), step + 1)
                if not ok.any():
                    continue
                terms_array, decrease, df = terms_array[ok], decrease[ok], df[ok]
                if columns is not None:
                    columns = [c for c, good in zip(columns, ok, strict=True) if good]
            f_stat, p_value, score, value = self._score_add(
                n, group_k, sse, group_problem.sst, decrease, df
            )
            j = int(score.argmin())  # terms in canonical order: ties go to the first
            best_score = float(score[j])
            if best_score != best_score:  # argmin found a NaN (0/0), which never enters
                score = np.where(score != score, np.inf, score)
                j = int(score.argmin())
                best_score = float(score[j])
            term = int(terms_array[j])
            candidate = (best_score, term)
            if best is None or candidate < best[0]:
                change = best_score if self.criterion in ("aic", "bic") else -best_score
                df_j = df if isinstance(df, float) else df[j]
                record = self._record(f_stat[j], p_value[j], value[j], change, df_j, n)
                chosen = [int(self.layout.first_column[term])] if columns is None else columns[j]
                best = (candidate, term, (best_score, *record), chosen, group_rows[key])
        if best is None:
            return None
        _, term, record, columns, new_rows = best
        return term, record, columns, new_rows

    def _record(self, f_stat, p_value, value, change, df, n) -> tuple:
        record = [float(f_stat), float(p_value)]
        if self.criterion != "sse":
            record += [float(value), float(change)]
        return (*record, int(df), int(n))

    def _worst_removal(self, terms, removable, matrix, n, k, sse, sst):
        y = self.y_slot
        increase = np.full(len(terms), np.nan)
        df = np.zeros(len(terms))
        if self.layout.single and all(self.swept.get(t) for t in terms.tolist()[1:]):
            # one column per term: SSE_small - SSE_large = b_j² / [(XᵀX)⁻¹]_jj
            columns = self.layout.first_column[terms[removable]]
            increase[removable] = matrix[columns, y] ** 2 / -matrix[columns, columns]
            df[removable] = 1.0
            terms_loop: list[int] = []
        else:
            terms_loop = terms.tolist()
        for position, term in enumerate(terms_loop):
            if not removable[position]:
                continue
            cols = self.swept.get(term, [])
            if not cols:
                continue
            if len(cols) == 1:
                c = cols[0]
                increase[position] = matrix[c, y] ** 2 / -matrix[c, c]
            else:
                b = matrix[cols, y]
                inverse_block = -matrix[np.ix_(cols, cols)]  # [(XᵀX)⁻¹]_TT
                increase[position] = float(b @ np.linalg.solve(inverse_block, b))
            df[position] = len(cols)
        dfe = n - k
        f_stat = (increase / np.maximum(df, 1)) / (sse / dfe)
        p_value = _f_sf(f_stat, np.maximum(df, 1), dfe)
        criterion = self.criterion
        if criterion == "sse":
            score = p_value
            value = np.full_like(p_value, np.nan)
            change = score
        elif criterion in ("aic", "bic"):
            penalty = 2.0 if criterion == "aic" else math.log(n)
            score = n * np.log(sse / (sse + increase)) + penalty * df  # Δ of adding it back
            value = n * (np.log(2 * np.pi * (sse + increase) / n) + 1.0) + penalty * (k - df)
            change = score
        elif criterion == "rsquared":
            score = -(increase / sst)
            value = 1.0 - (sse + increase) / sst
            change = -score
        else:
            with_term = 1.0 - (sse / dfe) / (sst / (n - 1))
            value = 1.0 - ((sse + increase) / (dfe + df)) / (sst / (n - 1))
            score = -(with_term - value)
            change = -score
        valid = removable & ~np.isnan(score) & (df > 0)
        if not valid.any():
            return None
        score = np.where(valid, score, -np.inf)
        worst = int(np.argmax(score))  # model is in canonical order: ties go first
        record = self._record(
            f_stat[worst], p_value[worst], value[worst], change[worst], df[worst], n
        )
        return int(terms[worst]), (float(score[worst]), *record)

    # ----------------------------------------------------------------- the result
    def result(self, encoding: Encoding, response_name: str, missing: str) -> StepwiseFit:
        layout = self.layout
        problem, matrix, rows = self.final
        model = self.model
        labels = _model_labels(layout, tuple(model))
        n = problem.n
        swept = self._model_columns()
        k = 1 + len(swept)
        dfe = n - k
        slope_columns = labels.slope_columns  # labels.columns[0] is the intercept
        m = len(slope_columns)
        index = labels.slope_index  # slope_columns as an index array (cached per model)
        # back from centred-scaled columns: b = b_z / s, V = (X_cᵀX_c)⁻¹ = V_z / (s sᵀ)
        if swept == slope_columns:
            scale = problem.scale[index]
            slopes = matrix[index, self.y_slot] / scale
            covariance = -matrix[labels.slope_rows, index] / (scale[:, None] * scale)
        else:  # columns left out as collinear: estimate 0 (MATLAB's rank-deficient fit)
            scale = problem.scale[swept]
            swept_slopes = matrix[swept, self.y_slot] / scale
            swept_covariance = -matrix[np.ix_(swept, swept)] / (scale[:, None] * scale)
            position = {c: j for j, c in enumerate(slope_columns)}
            swept_position = [position[c] for c in swept]
            slopes = np.zeros(m)
            covariance = np.zeros((m, m))
            slopes[swept_position] = swept_slopes
            covariance[np.ix_(swept_position, swept_position)] = swept_covariance
        term_means = problem.means[index]
        intercept = problem.y_mean - float(term_means @ slopes)
        residual = problem.y_centred - problem.centred[:, index] @ slopes
        sse = float(residual @ residual)
        sst = problem.sst
        mse = sse / dfe if dfe > 0 else math.nan
        rmse = math.sqrt(mse) if mse == mse else math.nan
        search_estimates = np.empty(m + 1)
        search_estimates[0] = intercept
        search_estimates[1:] = slopes
        r_squared = 1.0 - sse / sst if sst > 0 else math.nan
        adj_r_squared = 1.0 - (sse / dfe) / (sst / (n - 1)) if sst > 0 and dfe > 0 else math.nan
        if k > 1 and dfe > 0 and mse > 0:
            f_stat = ((sst - sse) / (k - 1)) / mse
            f_p_value = float(_f_sf(f_stat, k - 1, dfe))
        else:
            f_stat = f_p_value = math.nan
        log_likelihood = -0.5 * n * (math.log(2 * math.pi * sse / n) + 1.0) if sse > 0 else math.inf
        return StepwiseFit(
            terms=labels.display,
            predictor_names=encoding.names,
            response_name=response_name,
            criterion=self.criterion,
            p_enter=self.p_enter,
            p_remove=self.p_remove,
            n_obs=int(n),
            dfe=int(dfe),
            sse=sse,
            rmse=float(rmse),
            r_squared=float(r_squared),
            adj_r_squared=float(adj_r_squared),
            f_stat=float(f_stat),
            f_p_value=float(f_p_value),
            log_likelihood=float(log_likelihood),
            aic=float(-2.0 * log_likelihood + 2.0 * k),
            bic=float(-2.0 * log_likelihood + math.log(n) * k),
            model_terms=labels.terms,
            search_estimates=search_estimates,
            term_means=term_means,
            slope_covariance=covariance,
            step_records=tuple(self.steps),
            skipped_records=tuple((s, term, reason) for (term, reason), s in self.skipped.items()),
            coefficient_names=labels.column_names,
            coefficient_terms=labels.column_terms,
            encoding=encoding,
            missing=missing,
            search_warnings=tuple(self.warnings),
        )
